// Shape transforms and vertex attributes as the scene format defines them: the transform
// operations against their definitions, the order they compose in, what they do to normals and
// winding, OBJ texture coordinates and normals welded per vertex, and clear errors for each kind
// of bad transform.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/math/transform.h"
#include "common/scene/parser.h"
#include "common/scene/scene_files.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

void expect_near(const WideVec3& a, const WideVec3& b, double tol = 1e-12) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

void expect_near(const Vec3& a, const Vec3& b, float tol = 1e-6f) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

TEST(TransformTest, OperationsFollowTheirDefinitions) {
  expect_near(Transform::translate({1, 2, 3}).point({1, 1, 1}), {2, 3, 4});
  expect_near(Transform::translate({1, 2, 3}).vector({1, 1, 1}), {1, 1, 1});
  expect_near(Transform::scale({2, 3, 4}).point({1, 1, 1}), {2, 3, 4});
  // Right hand: +90 degrees about +z takes +x to +y, about +x takes +y to +z.
  expect_near(Transform::rotate({0, 0, 1}, 90).point({1, 0, 0}), {0, 1, 0});
  expect_near(Transform::rotate({1, 0, 0}, 90).point({0, 1, 0}), {0, 0, 1});
  // look_at: local +z points at the target, local origin sits at the eye.
  const Transform la = Transform::look_at({1, 2, 3}, {1, 2, 10}, {0, 1, 0});
  expect_near(la.point({0, 0, 0}), {1, 2, 3});
  expect_near(la.vector({0, 0, 1}), {0, 0, 1});
  expect_near(la.vector({0, 1, 0}), {0, 1, 0});
  EXPECT_NEAR(la.determinant(), 1.0, 1e-12);
}

TEST(TransformTest, ThenAppliesTheFirstOperationFirst) {
  const Transform t = Transform::scale({2, 2, 2}).then(Transform::translate({1, 0, 0}));
  expect_near(t.point({1, 0, 0}), {3, 0, 0});  // scaled to 2, then moved to 3
  const Transform u = Transform::translate({1, 0, 0}).then(Transform::scale({2, 2, 2}));
  expect_near(u.point({1, 0, 0}), {4, 0, 0});  // moved to 2, then scaled to 4
}

TEST(TransformTest, NormalsStayPerpendicularUnderNonUniformScale) {
  const Transform t = Transform::scale({1, 4, 1}).then(Transform::rotate({1, 2, 3}, 37));
  const WideVec3 tangent{1, -1, 0}, normal{1, 1, 0};  // perpendicular before
  const WideVec3 a = t.vector(tangent), n = t.normal(normal);
  EXPECT_NEAR(a.x * n.x + a.y * n.y + a.z * n.z, 0.0, 1e-12);
  EXPECT_EQ(t.uniform_scale(), 0.0);
  EXPECT_NEAR(Transform::scale({3, 3, 3}).then(Transform::rotate({0, 1, 0}, 20)).uniform_scale(),
              3.0, 1e-12);
}

/// A scene of one shape (its JSON object), loaded.
Scene load_one_shape(TempDir& dir, const std::string& shape) {
  const fs::path file = dir.write("scene.json", R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40},
  "film": {"width": 8, "height": 8},
  "materials": {"m": {"type": "diffuse"}},
  "shapes": [)" + shape + "]}");
  return load_scene(file);
}

Vec3 triangle_normal_of(const TriangleMesh& mesh, size_t t) {
  const Vec3& a = mesh.positions[mesh.indices[3 * t]];
  const Vec3& b = mesh.positions[mesh.indices[3 * t + 1]];
  const Vec3& c = mesh.positions[mesh.indices[3 * t + 2]];
  return normalize(cross(b - a, c - a));
}

TEST(ShapeTransformTest, QuadMovesAndKeepsItsFrontUnderAMirror) {
  TempDir dir;
  // edge1 x edge2 = +x x +y = +z; translated by +10 z, then mirrored in x: the front must still
  // face +z (a mirror image of a surface facing +z faces +z).
  const Scene scene = load_one_shape(dir, R"({"type": "quad", "corner": [0, 0, 0],
      "edge1": [1, 0, 0], "edge2": [0, 1, 0], "material": "m",
      "transform": [{"translate": [0, 0, 10]}, {"scale": [-1, 1, 1]}]})");
  ASSERT_EQ(scene.meshes.size(), 1u);
  const TriangleMesh& mesh = scene.meshes[0];
  for (const Vec3& p : mesh.positions) {
    EXPECT_EQ(p.z, 10.f);
    EXPECT_LE(p.x, 0.f);
  }
  for (size_t t = 0; t < mesh.triangle_count(); ++t)
    expect_near(triangle_normal_of(mesh, t), {0, 0, 1});
}

TEST(ShapeTransformTest, VertexNormalsStayOnTheFrontUnderAMirror) {
  TempDir dir;
  dir.write("m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n");
  const Scene scene = load_one_shape(dir, R"({"type": "mesh", "file": "m.obj",
      "transform": {"scale": [-1, 2, 1]}})");
  const TriangleMesh& mesh = scene.meshes.at(0);
  const Vec3 front = triangle_normal_of(mesh, 0);
  expect_near(front, {0, 0, 1});
  for (const Vec3& n : mesh.normals) expect_near(n, front);
}

TEST(ShapeTransformTest, MatrixFormEqualsTheOperations) {
  TempDir dir;
  const Scene a = load_one_shape(dir, R"({"type": "triangle", "material": "m",
      "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
      "transform": [{"rotate": {"axis": [0, 0, 1], "angle": 90}}, {"translate": [5, 0, 0]}]})");
  const Scene b = load_one_shape(dir, R"({"type": "triangle", "material": "m",
      "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
      "transform": [0, -1, 0, 5,  1, 0, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]})");
  ASSERT_EQ(a.meshes.size(), 1u);
  ASSERT_EQ(b.meshes.size(), 1u);
  for (size_t i = 0; i < 3; ++i) expect_near(a.meshes[0].positions[i], b.meshes[0].positions[i]);
  expect_near(a.meshes[0].positions[1], {5, 1, 0});
}

TEST(ShapeTransformTest, SphereTakesSimilaritiesAndItsFrameTurns) {
  TempDir dir;
  const Scene scene = load_one_shape(dir, R"({"type": "sphere", "center": [1, 0, 0],
      "radius": 2, "material": "m",
      "transform": [{"scale": 3}, {"rotate": {"axis": [0, 0, 1], "angle": 90}}]})");
  ASSERT_EQ(scene.spheres.size(), 1u);
  const Sphere& s = scene.spheres[0];
  expect_near(s.center, {0, 3, 0}, 1e-5f);
  EXPECT_FLOAT_EQ(s.radius, 6.f);
  expect_near(s.axis_x, {0, 1, 0});
  expect_near(s.axis_y, {-1, 0, 0});
  expect_near(s.axis_z, {0, 0, 1});
}

void expect_load_error(const std::string& shape, const std::string& part) {
  TempDir dir;
  try {
    load_one_shape(dir, shape);
    ADD_FAILURE() << "expected an error for " << shape;
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("/shapes/0/transform"), std::string::npos) << e.what();
  }
}

TEST(ShapeTransformTest, BadTransformsAreErrorsThatSayWhere) {
  const std::string tri = R"({"type": "triangle", "material": "m",
      "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "transform": )";
  expect_load_error(tri + "[{\"scale\": [1, 0, 1]}]}", "must not be zero");
  expect_load_error(tri + "[1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 1, 1]}", "0 0 0 1");
  expect_load_error(tri + "[1, 0, 0]}", "16 numbers");
  expect_load_error(tri + "[1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 0, 0,  0, 0, 0, 1]}", "singular");
  expect_load_error(tri + "[{\"shear\": 1}]}", "unknown transform operation");
  expect_load_error(tri + "[{\"translate\": [1, 0, 0], \"scale\": 2}]}", "exactly one key");
  expect_load_error(tri + "{\"rotate\": {\"axis\": [0, 0, 0], \"angle\": 3}}}", "axis");
  expect_load_error(tri + "{\"look_at\": {\"eye\": [0, 0, 0], \"target\": [0, 5, 0]}}}",
                    "parallel");
  expect_load_error(tri + "{\"scale\": 1e18}}", "beyond 1e17");
  expect_load_error(R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m",
      "transform": {"scale": [1, 2, 1]}})",
                    "scale all directions alike");
}

TEST(ObjAttributesTest, EachVertexCarriesItsOwnTexcoordAndNormal) {
  TempDir dir;
  // Two triangles share positions 1 and 3 but not their texture coordinates: those vertices must
  // be split, each copy carrying the pair its corner named.
  dir.write("m.obj",
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
            "vn 0 0 2\nvn 0 1 1\n"
            "f 1/1/1 2/2/1 3/3/2\n"
            "f 1/5/1 3/3/2 4\n");
  const Scene scene = load_one_shape(dir, R"({"type": "mesh", "file": "m.obj"})");
  ASSERT_EQ(scene.meshes.size(), 1u);
  const TriangleMesh& mesh = scene.meshes[0];
  ASSERT_EQ(mesh.triangle_count(), 2u);
  ASSERT_EQ(mesh.positions.size(), 5u);  // 1/1/1, 2/2/1, 3/3/2, 1/5/1, 4//
  ASSERT_EQ(mesh.uvs.size(), 5u);
  ASSERT_EQ(mesh.normals.size(), 5u);
  auto corner = [&](size_t t, size_t k) { return mesh.indices[3 * t + k]; };
  EXPECT_EQ(mesh.positions[corner(0, 0)], mesh.positions[corner(1, 0)]);
  EXPECT_NE(corner(0, 0), corner(1, 0));  // same position, other texcoord
  EXPECT_EQ(corner(0, 2), corner(1, 1));  // 3/3/2 both times: one vertex
  EXPECT_EQ(mesh.uvs[corner(1, 0)], Vec2(0.5f, 0.5f));
  expect_near(mesh.normals[corner(0, 0)], {0, 0, 1});  // normalised on reading
  expect_near(mesh.normals[corner(0, 2)], {0, std::sqrt(0.5f), std::sqrt(0.5f)});
  EXPECT_EQ(mesh.normals[corner(1, 2)], Vec3(0.f));  // no normal given: flat there
  EXPECT_EQ(mesh.uvs[corner(1, 2)], Vec2(0.f, 0.f));
}

TEST(ObjAttributesTest, PlainFacesKeepThePositionsAsWritten) {
  TempDir dir;
  dir.write("m.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 5 5 5\nvt 0 0\nf 1 2 3\n");
  const Scene scene = load_one_shape(dir, R"({"type": "mesh", "file": "m.obj"})");
  const TriangleMesh& mesh = scene.meshes.at(0);
  EXPECT_EQ(mesh.positions.size(), 4u);
  EXPECT_TRUE(mesh.uvs.empty());
  EXPECT_TRUE(mesh.normals.empty());
}

// An OBJ file of `count` objects, each one triangle over the same three vertices.
std::string one_triangle_objects(size_t count) {
  std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  for (size_t i = 0; i < count; ++i) text += "o x\nf 1 2 3\n";
  return text;
}

TEST(ObjObjectsTest, EachObjectOrGroupBecomesAMeshOfItsOwn) {
  TempDir dir;
  // Three objects over shared vertex lists: a wall (two triangles, with texture coordinates),
  // a group with one triangle, and a trailing "o" with no faces, which names nothing.
  dir.write("m.mtl", "newmtl a\nKd 1 0 0\nnewmtl b\nKd 0 1 0\n");
  dir.write("m.obj",
            "mtllib m.mtl\n"
            "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 9 9 9\nv 1 1 1\nv 2 1 1\nv 1 2 1\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
            "o wall\nusemtl a\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
            "g block\nusemtl b\nf 6 7 8\n"
            "o empty\n");
  const Scene scene = load_one_shape(dir, R"({"type": "mesh", "file": "m.obj"})");
  ASSERT_EQ(scene.meshes.size(), 2u);
  const TriangleMesh& wall = scene.meshes[0];
  const TriangleMesh& block = scene.meshes[1];
  ASSERT_EQ(wall.triangle_count(), 2u);
  ASSERT_EQ(block.triangle_count(), 1u);
  // Each keeps the vertices its triangles use, and nothing else (not v 9 9 9).
  EXPECT_EQ(wall.positions.size(), 4u);
  EXPECT_EQ(wall.uvs.size(), 4u);
  ASSERT_EQ(block.positions.size(), 3u);
  EXPECT_EQ(block.uvs.size(), 3u);  // the file's welded vertices all carry one
  EXPECT_EQ(block.positions[block.indices[0]], Vec3(1, 1, 1));
  EXPECT_EQ(block.positions[block.indices[2]], Vec3(1, 2, 1));
  EXPECT_EQ(wall.positions[wall.indices[5]], Vec3(0, 4, 0));
  EXPECT_EQ(wall.uvs[wall.indices[5]], Vec2(0, 1));
  // Materials follow their triangles; origins say which object.
  EXPECT_EQ(scene.materials[wall.materials[0]].name, "m.obj:a");
  EXPECT_EQ(scene.materials[block.materials[0]].name, "m.obj:b");
  EXPECT_EQ(wall.origin, "m.obj (object \"wall\")");
  EXPECT_EQ(block.origin, "m.obj (object \"block\")");
  // Faces before any o or g are an object without a name; of two names in a row, the later one
  // names the faces that follow.
  dir.write("n.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no first\no second\nf 3 2 1\n");
  const Scene named = load_one_shape(dir, R"({"type": "mesh", "file": "n.obj"})");
  ASSERT_EQ(named.meshes.size(), 2u);
  EXPECT_EQ(named.meshes[0].origin, "n.obj (object 1)");
  EXPECT_EQ(named.meshes[1].origin, "n.obj (object \"second\")");
}

TEST(ObjObjectsTest, OneObjectOrTooManyStayOneMesh) {
  TempDir dir;
  dir.write("one.obj", "o only\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 3 2 1\n");
  EXPECT_EQ(load_one_shape(dir, R"({"type": "mesh", "file": "one.obj"})").meshes.size(), 1u);
  // Exactly the most objects that are split, and one more.
  const std::string most = one_triangle_objects(kMaxMeshObjects);
  dir.write("most.obj", most);
  dir.write("many.obj", most + "o x\nf 1 2 3\n");
  EXPECT_EQ(load_one_shape(dir, R"({"type": "mesh", "file": "most.obj"})").meshes.size(),
            kMaxMeshObjects);
  const Scene scene = load_one_shape(dir, R"({"type": "mesh", "file": "many.obj"})");
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].triangle_count(), kMaxMeshObjects + 1);
}

TEST(ObjObjectsTest, AScenesSplitMeshesHaveABudget) {
  // A small scene naming a file of 4,096 one-triangle objects again and again: once the split
  // meshes would pass kMaxSplitMeshes, the files stay whole.
  TempDir dir;
  dir.write("most.obj", one_triangle_objects(kMaxMeshObjects));
  const size_t files = kMaxSplitMeshes / kMaxMeshObjects + 2;
  std::string shapes;
  for (size_t i = 0; i < files; ++i)
    shapes += std::string(i ? ", " : "") + R"({"type": "mesh", "file": "most.obj"})";
  const Scene scene = load_one_shape(dir, shapes);
  const size_t split = kMaxSplitMeshes / kMaxMeshObjects;
  EXPECT_EQ(scene.meshes.size(), split * kMaxMeshObjects + (files - split));
  size_t triangles = 0;
  for (const TriangleMesh& m : scene.meshes) triangles += m.triangle_count();
  EXPECT_EQ(triangles, files * kMaxMeshObjects);
}

TEST(CameraInputTest, OrthographicTakesAViewHeightInsteadOfAFieldOfView) {
  TempDir dir;
  const std::string head = R"({"film": {"width": 8, "height": 8}, "camera": {"type": "orthographic",
      "eye": [0, 0, -5], "look_at": [0, 0, 0])";
  const Scene scene = load_scene(dir.write("a.json", head + R"(, "view_height": 3}})"));
  EXPECT_EQ(scene.camera.projection, Camera::Projection::kOrthographic);
  EXPECT_EQ(scene.camera.view_height, 3.f);
  try {
    load_scene(dir.write("b.json", head + "}}"));
    ADD_FAILURE() << "an orthographic camera without view_height loaded";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("/camera: missing key \"view_height\""), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace rayfarm
