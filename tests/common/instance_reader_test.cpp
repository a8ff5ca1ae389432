// Mesh groups and their instances in the JSON format: what the reader fills, how placing a group
// keeps front faces outward under a mirror, and every refusal naming its place.
#include <gtest/gtest.h>

#include <initializer_list>
#include <string>

#include "common/scene/instances.h"
#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

std::string scene_with(const std::string& extra) {
  return R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
  "film": {"width": 16, "height": 16},
  "materials": {"m": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]},
                "lamp": {"type": "diffuse", "albedo": [0, 0, 0], "emission": [1, 1, 1]}},
  )" + extra +
         "\n}\n";
}

const std::string kGroups = R"("groups": {
    "tile": [{"type": "quad", "corner": [0, 0, 0], "edge1": [1, 0, 0], "edge2": [0, 1, 0],
              "material": "m"}],
    "lamp": [{"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
              "material": "lamp"}]
  })";

Scene load(const std::string& extra) {
  TempDir dir;
  return load_scene(dir.write("scene.json", scene_with(extra)));
}

void expect_scene_error(const std::string& extra, std::initializer_list<std::string> parts) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", scene_with(extra));
  try {
    const Scene scene = load_scene(file);
    ADD_FAILURE() << "expected a SceneError for:\n" << extra;
  } catch (const SceneError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(file.string()), std::string::npos) << message;
    for (const std::string& part : parts)
      EXPECT_NE(message.find(part), std::string::npos) << "\"" << part << "\" not in: " << message;
  }
}

TEST(InstanceReader, GroupsAndInstancesAsWritten) {
  const Scene scene = load(kGroups + R"(,
  "shapes": [
    {"type": "instance", "group": "tile"},
    {"type": "instance", "group": "tile", "transform": {"translate": [2, 3, 4]}},
    {"type": "instance", "group": "lamp", "transform": [2, 0, 0, 1, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1]}
  ])");
  ASSERT_EQ(scene.groups.size(), 2u);
  EXPECT_TRUE(scene.meshes.empty());  // a group's meshes are not world meshes
  const MeshGroup& tile = scene.groups.at(scene.instances.at(0).group);
  EXPECT_EQ(tile.name, "tile");
  ASSERT_EQ(tile.meshes.size(), 1u);
  EXPECT_EQ(tile.meshes[0].triangle_count(), 2u);
  ASSERT_EQ(scene.instances.size(), 3u);
  const std::array<double, 16> identity{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  EXPECT_EQ(scene.instances[0].world_from_object, identity);
  const std::array<double, 16> moved{1, 0, 0, 2, 0, 1, 0, 3, 0, 0, 1, 4, 0, 0, 0, 1};
  EXPECT_EQ(scene.instances[1].world_from_object, moved);
  EXPECT_EQ(scene.instances[1].group, scene.instances[0].group);
  EXPECT_EQ(scene.groups.at(scene.instances[2].group).name, "lamp");
  EXPECT_EQ(scene.instances[2].world_from_object[0], 2.0);
  EXPECT_EQ(scene.instances[2].world_from_object[3], 1.0);
}

TEST(InstanceReader, RefusalsNameTheirPlace) {
  expect_scene_error(kGroups + R"(, "shapes": [{"type": "instance", "group": "tiles"}])",
                     {"/shapes/0/group", "unknown group \"tiles\"", "defined: lamp, tile"});
  expect_scene_error(R"("shapes": [{"type": "instance", "group": "tile"}])",
                     {"/shapes/0/group", "no groups are defined"});
  expect_scene_error(
      R"("groups": {"g": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}]})",
      {"/groups/g/0/type", "meshes, quads and triangles only", "sphere"});
  expect_scene_error(R"("groups": {"g": [{"type": "instance", "group": "g"}]})",
                     {"/groups/g/0/type", "instance"});
  expect_scene_error(kGroups + R"(, "shapes": [{"type": "instance", "group": "tile",
      "transform": {"scale": [1, 0, 1]}}])",
                     {"/shapes/0/transform"});
  expect_scene_error(kGroups + R"(, "shapes": [{"type": "instance", "group": "tile",
      "transform": {"scale": [1e18, 1, 1]}}])",
                     {"/shapes/0/transform", "beyond"});
  expect_scene_error(R"("groups": {"g": 3})", {"/groups/g", "expected an array"});
}

// Instances of an emissive group are copied into the world for light sampling, so the
// triangles they place are bounded like world triangles: 2^15 triangles placed 2049 times is
// just over 2^26.
TEST(InstanceReader, EmissiveInstancesAreBoundedLikeWorldTriangles) {
  TempDir dir;
  std::string obj;
  const int n = 128;  // a grid of n x n squares: 2 n^2 = 2^15 triangles
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) obj += "v " + std::to_string(x) + " " + std::to_string(y) + " 0\n";
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const int a = y * (n + 1) + x + 1, b = a + 1, c = a + n + 1, d = c + 1;
      obj += "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(d) + "\n";
      obj += "f " + std::to_string(a) + " " + std::to_string(d) + " " + std::to_string(c) + "\n";
    }
  }
  dir.write("grid.obj", obj);
  auto scene_placing = [&](const std::string& material, int count) {
    std::string shapes;
    for (int i = 0; i < count; ++i)
      shapes += std::string(i ? "," : "") + R"({"type": "instance", "group": "grid"})";
    return scene_with(R"("groups": {"grid": [{"type": "mesh", "file": "grid.obj", "material": ")" +
                      material + R"("}]}, "shapes": [)" + shapes + "]");
  };
  const fs::path lit = dir.write("lit.json", scene_placing("lamp", 2049));
  try {
    load_scene(lit);
    ADD_FAILURE() << "2^26 + 2^15 emissive instanced triangles loaded";
  } catch (const SceneError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("/shapes/2048"), std::string::npos) << message;
    EXPECT_NE(message.find("instances of emissive groups place more than 67108864"),
              std::string::npos)
        << message;
  }
  // The same placements of a group that does not emit cost one copy of it: accepted.
  const Scene dark = load_scene(dir.write("dark.json", scene_placing("m", 2049)));
  EXPECT_EQ(dark.instances.size(), 2049u);
}

// A mirrored placement reverses the winding back, so that the geometric front face and the
// vertex normals keep pointing the way the mirror image of the surface does.
TEST(InstanceReader, MirroredPlacementKeepsFrontFacesOutward) {
  TriangleMesh mesh;
  mesh.positions = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};  // front face +z
  mesh.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  mesh.indices = {0, 1, 2};
  mesh.materials = {0};
  // Mirror in z: the surface moves to z = -1 and, seen from outside (the +z side before), its
  // front now faces -z.
  const TriangleMesh placed = place_mesh(mesh, Transform::scale({1, 1, -1}));
  const Vec3 a = placed.positions[placed.indices[0]], b = placed.positions[placed.indices[1]],
             c = placed.positions[placed.indices[2]];
  EXPECT_EQ(a.z, -1.f);
  EXPECT_LT(cross(b - a, c - a).z, 0.f);
  for (const Vec3& n : placed.normals) EXPECT_EQ(n, Vec3(0.f, 0.f, -1.f));
  // Mirror in x: the face still faces +z, and so do its normals.
  const TriangleMesh side = place_mesh(mesh, Transform::scale({-1, 1, 1}));
  const Vec3 p = side.positions[side.indices[0]], q = side.positions[side.indices[1]],
             r = side.positions[side.indices[2]];
  EXPECT_GT(cross(q - p, r - p).z, 0.f);
  for (const Vec3& n : side.normals) EXPECT_EQ(n, Vec3(0.f, 0.f, 1.f));
}

// Emissive groups become world meshes (area lights need world-space triangles); the others stay
// instances, their triangles stored once.
TEST(InstanceReader, FlatteningEmissiveInstancesOnly) {
  Scene scene = load(kGroups + R"(, "shapes": [
    {"type": "instance", "group": "tile"},
    {"type": "instance", "group": "lamp", "transform": {"translate": [0, 0, 3]}},
    {"type": "instance", "group": "tile", "transform": {"translate": [5, 0, 0]}}
  ])");
  EXPECT_EQ(flatten_instances(scene, true), 1u);
  ASSERT_EQ(scene.instances.size(), 2u);
  for (const Instance& i : scene.instances) EXPECT_EQ(scene.groups[i.group].name, "tile");
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].positions[0], Vec3(0.f, 0.f, 3.f));
  EXPECT_EQ(flatten_instances(scene, false), 2u);
  EXPECT_TRUE(scene.instances.empty());
  EXPECT_EQ(scene.meshes.size(), 3u);
  EXPECT_EQ(scene.meshes[2].positions[0], Vec3(5.f, 0.f, 0.f));
}

// Every material works in a group: cut-outs, normal and bump maps and anisotropic roughness are
// read in the group's space (tests/renderer/instance_surface_test.cpp renders them).
TEST(InstanceReader, GroupsWithSurfaceFeaturesAccepted) {
  const char* materials[] = {
      R"({"type": "diffuse", "opacity": 0.2})",
      R"({"type": "diffuse", "normal_map": {"texture": "check"}})",
      R"({"type": "diffuse", "bump_map": {"texture": "check", "scale": 0.1}})",
      R"({"type": "roughconductor", "alpha_u": 0.1, "alpha_v": 0.3})",
  };
  for (const char* material : materials) {
    TempDir dir;
    const fs::path file = dir.write("scene.json", std::string(R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
  "film": {"width": 16, "height": 16},
  "textures": {"check": {"type": "checkerboard", "color0": [0.8, 0.8, 0.8], "color1": [0.1, 0.1, 0.1]}},
  "materials": {"plain": {"type": "diffuse"}, "odd": )") +
                                                      material + R"(},
  "groups": {"g": [
    {"type": "quad", "corner": [0, 0, 0], "edge1": [1, 0, 0], "edge2": [0, 1, 0], "material": "plain"},
    {"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "material": "odd"}]},
  "shapes": [{"type": "instance", "group": "g"}]
})");
    Scene scene;
    ASSERT_NO_THROW(scene = load_scene(file)) << material;
    ASSERT_EQ(scene.groups.size(), 1u);
    EXPECT_EQ(scene.groups[0].meshes.size(), 2u) << material;
    EXPECT_EQ(scene.instances.size(), 1u) << material;
  }
}

// Tangents turn with the mesh; a mirror flips their handedness, as it flips the bitangent.
TEST(InstanceReader, PlacedTangentsFollowTheTransform) {
  TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.indices = {0, 1, 2};
  mesh.materials = {0};
  mesh.tangents.assign(3, Vec4(1.f, 0.f, 0.f, 1.f));
  const TriangleMesh turned = place_mesh(mesh, Transform::scale({1, 3, 1}));
  for (const Vec4& t : turned.tangents) EXPECT_EQ(t, Vec4(1.f, 0.f, 0.f, 1.f));
  const TriangleMesh mirrored = place_mesh(mesh, Transform::scale({-2, 1, 1}));
  for (const Vec4& t : mirrored.tangents) EXPECT_EQ(t, Vec4(-1.f, 0.f, 0.f, -1.f));
}

}  // namespace
}  // namespace rayfarm
