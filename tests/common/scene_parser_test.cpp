// The scene parser: the bundled scenes load as written, and every kind of bad input is rejected
// with a SceneError that names the file and the place (JSON pointer or line), never a crash.
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <fstream>
#include <initializer_list>
#include <map>
#include <random>
#include <set>
#include <string>
#include <variant>

#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

fs::path bundled(const std::string& name) {
  return fs::path(RAYFARM_SOURCE_DIR) / "scenes" / name / "scene.json";
}

using testing::read_file;
using testing::TempDir;

/// A valid scene with `extra` top-level members added after camera and film.
std::string scene_with(const std::string& extra) {
  std::string json = R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
  "film": {"width": 16, "height": 16})";
  if (!extra.empty()) json += ",\n  " + extra;
  return json + "\n}\n";
}

const std::string kMaterials =
    R"("materials": {"m": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}})";

/// Loads `file`, expecting a SceneError whose message contains every one of `parts`.
void expect_error(const fs::path& file, std::initializer_list<std::string> parts) {
  try {
    const Scene scene = load_scene(file);
    ADD_FAILURE() << "expected a SceneError for " << file << ":\n" << read_file(file);
  } catch (const SceneError& e) {
    const std::string message = e.what();
    for (const std::string& part : parts) {
      EXPECT_NE(message.find(part), std::string::npos) << "\"" << part << "\" not in: " << message;
    }
  }
}

/// Expects a SceneError naming the scene file and `pointer` for a scene built from `extra`.
void expect_scene_error(const std::string& extra, std::initializer_list<std::string> parts) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", scene_with(extra));
  expect_error(file, parts);
  expect_error(file, {file.string()});
}

Vec3 front_normal(const TriangleMesh& mesh, size_t triangle) {
  const Vec3& a = mesh.positions[mesh.indices[3 * triangle]];
  const Vec3& b = mesh.positions[mesh.indices[3 * triangle + 1]];
  const Vec3& c = mesh.positions[mesh.indices[3 * triangle + 2]];
  return normalize(cross(b - a, c - a));
}

Vec3 centroid(const TriangleMesh& mesh, size_t triangle) {
  Vec3 sum;
  for (size_t k = 0; k < 3; ++k) sum += mesh.positions[mesh.indices[3 * triangle + k]];
  return sum / 3.f;
}

size_t triangle_count(const Scene& scene) {
  size_t count = 0;
  for (const TriangleMesh& mesh : scene.meshes) count += mesh.triangle_count();
  return count;
}

const Material& material_named(const Scene& scene, const std::string& name) {
  for (const Material& m : scene.materials) {
    if (m.name == name) return m;
  }
  ADD_FAILURE() << "no material " << name;
  return scene.materials.front();
}

/// m's parameters, which must be of kind K (std::get throws otherwise, failing the test).
template <class K>
const K& params(const Material& m) {
  EXPECT_TRUE(std::holds_alternative<K>(m.kind)) << m.name << " is " << material_kind_name(m.kind);
  return std::get<K>(m.kind);
}

/// The scene's warnings but the one every scene without light gets (tested in
/// gltf_conformance_test.cpp): these scenes are unlit on purpose.
std::vector<std::string> warnings(const Scene& scene) {
  std::vector<std::string> out;
  for (const std::string& w : scene.warnings)
    if (w.find(kNoLightWarning) == std::string::npos) out.push_back(w);
  return out;
}

std::string warnings_of(const Scene& scene) {
  std::string all;
  for (const std::string& w : warnings(scene)) all += w + "\n";
  return all;
}

// ---- bundled scenes --------------------------------------------------------------------------

TEST(SceneBundled, CornellBoxLoadsAsWritten) {
  const Scene scene = load_scene(bundled("cornell-box"));
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  EXPECT_EQ(scene.meshes.size(), 6u);  // floor, ceiling, back, red, green, light: one quad each
  EXPECT_EQ(triangle_count(scene), 12u);
  EXPECT_EQ(scene.spheres.size(), 2u);
  EXPECT_TRUE(scene.point_lights.empty());
  EXPECT_EQ(scene.materials.size(), 6u);
  EXPECT_EQ(scene.film.width, 256u);
  EXPECT_EQ(scene.film.height, 256u);
  EXPECT_EQ(scene.render.spp, 64u);
  EXPECT_EQ(scene.render.max_depth, 16u);
  EXPECT_EQ(scene.render.integrator, IntegratorType::kMis);
  EXPECT_EQ(scene.camera.eye, Vec3(278.f, 273.f, -800.f));
  EXPECT_EQ(scene.camera.fov_y_deg, 37.f);
  EXPECT_EQ(params<DielectricMaterial>(material_named(scene, "glass")).ior, 1.5f);
  EXPECT_TRUE(std::holds_alternative<MirrorMaterial>(material_named(scene, "mirror").kind));

  const Vec3 room_center{278.f, 274.4f, 279.6f};
  size_t emitters = 0;
  for (const TriangleMesh& mesh : scene.meshes) {
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
      const Vec3 n = front_normal(mesh, t);
      // Every wall, and the light, faces into the room.
      EXPECT_GT(dot(n, room_center - centroid(mesh, t)), 0.f) << mesh.origin;
      if (scene.materials[mesh.materials[t]].is_emissive()) {
        ++emitters;
        EXPECT_NEAR(n.y, -1.f, 1e-6f) << "the light must face down";
        EXPECT_LT(centroid(mesh, t).y, 548.8f);
      }
    }
  }
  EXPECT_EQ(emitters, 2u);
  for (const Sphere& s : scene.spheres) EXPECT_FLOAT_EQ(s.center.y, s.radius) << "on the floor";
}

TEST(SceneBundled, PhongLoadsAsWritten) {
  const Scene scene = load_scene(bundled("phong"));
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  EXPECT_EQ(triangle_count(scene), 4u);
  EXPECT_EQ(scene.spheres.size(), 4u);
  EXPECT_EQ(scene.point_lights.size(), 1u);
  EXPECT_EQ(scene.materials.size(), 6u);
  EXPECT_EQ(scene.film.width, 192u);
  EXPECT_EQ(scene.film.height, 128u);
  float previous = 0.f;
  for (const Sphere& s : scene.spheres) {
    const MaterialKind& kind = scene.materials[s.material].kind;
    ASSERT_TRUE(std::holds_alternative<PhongMaterial>(kind));
    const PhongMaterial& m = std::get<PhongMaterial>(kind);
    EXPECT_GT(m.exponent, previous);
    EXPECT_LE(max_component(m.kd + m.ks), 1.f);
    previous = m.exponent;
  }
  EXPECT_EQ(previous, 1000.f);
  for (const TriangleMesh& mesh : scene.meshes) {
    const bool lamp = scene.materials[mesh.materials[0]].is_emissive();
    EXPECT_NEAR(front_normal(mesh, 0).y, lamp ? -1.f : 1.f, 1e-6f) << mesh.origin;
  }
}

TEST(SceneBundled, FurnaceIsAClosedTwoSidedEmitter) {
  const Scene scene = load_scene(bundled("furnace"));
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  EXPECT_TRUE(scene.meshes.empty());
  EXPECT_TRUE(scene.point_lights.empty());
  ASSERT_EQ(scene.spheres.size(), 1u);
  const Sphere& s = scene.spheres[0];
  EXPECT_LT(length(scene.camera.eye - s.center), s.radius) << "the camera is inside";
  const Material& m = scene.materials[s.material];
  EXPECT_EQ(params<DiffuseMaterial>(m).albedo, Vec3(0.5f));
  EXPECT_EQ(m.emission, Vec3(1.f));
  EXPECT_TRUE(m.two_sided) << "the camera sees the sphere's back side";
}

TEST(SceneBundled, MaterialsHasEveryMicrofacetAndLayeredKind) {
  const Scene scene = load_scene(bundled("materials"));
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  EXPECT_EQ(scene.film.width, 320u);
  EXPECT_EQ(scene.film.height, 160u);
  EXPECT_EQ(params<RoughConductorMaterial>(material_named(scene, "rough-gold")).alpha_u, 0.2f);
  EXPECT_EQ(params<RoughDielectricMaterial>(material_named(scene, "rough-glass")).alpha_v, 0.15f);
  EXPECT_EQ(params<ThinDielectricMaterial>(material_named(scene, "pane")).ior, 1.5f);
  EXPECT_EQ(params<PlasticMaterial>(material_named(scene, "plastic")).alpha, 0.f);
  EXPECT_EQ(params<PlasticMaterial>(material_named(scene, "rough-plastic")).alpha, 0.25f);
  EXPECT_EQ(params<MetallicRoughnessMaterial>(material_named(scene, "gltf-metal")).metallic, 1.f);
  EXPECT_EQ(params<MetallicRoughnessMaterial>(material_named(scene, "gltf-dielectric")).metallic,
            0.f);
  EXPECT_EQ(scene.spheres.size(), 6u);
}

TEST(SceneBundled, ManyLightsHasSixtyFourLampsFacingDown) {
  const Scene scene = load_scene(bundled("many-lights"));
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  EXPECT_TRUE(scene.point_lights.empty());
  EXPECT_EQ(scene.render.max_depth, kUnlimitedDepth);
  // Each lamp a small one-sided quad just below the ceiling (y = 3), emitting downwards.
  int lamps = 0;
  for (const TriangleMesh& mesh : scene.meshes) {
    const Material& m = scene.materials[mesh.materials[0]];
    if (!m.is_emissive()) continue;
    ++lamps;
    EXPECT_FALSE(m.two_sided);
    ASSERT_EQ(mesh.indices.size(), 6u);
    const Vec3 n = cross(mesh.positions[mesh.indices[1]] - mesh.positions[mesh.indices[0]],
                         mesh.positions[mesh.indices[2]] - mesh.positions[mesh.indices[0]]);
    EXPECT_LT(n.y, 0.f) << mesh.origin << " faces down";
    for (const Vec3& p : mesh.positions) EXPECT_NEAR(p.y, 2.99f, 1e-5f) << mesh.origin;
  }
  EXPECT_EQ(lamps, 64);
  ASSERT_EQ(scene.spheres.size(), 1u);  // the glowing orb
  EXPECT_TRUE(scene.materials[scene.spheres[0].material].is_emissive());
}

TEST(SceneBundled, MaterialPreviewHasOneSphereOfEveryKind) {
  const Scene scene = load_scene(bundled("material-preview"));
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  EXPECT_EQ(scene.film.width, 384u);
  EXPECT_EQ(scene.film.height, 256u);
  EXPECT_EQ(scene.render.spp, 64u);
  EXPECT_EQ(scene.render.max_depth, 12u);
  EXPECT_EQ(scene.render.integrator, IntegratorType::kMis);

  // Lit by its sky alone: no emitter, no punctual light.
  ASSERT_TRUE(scene.environment);
  EXPECT_EQ(scene.environment->file, "sky.hdr");
  ASSERT_TRUE(scene.environment->image);
  EXPECT_EQ(scene.environment->image->width, 128u);
  EXPECT_EQ(scene.environment->image->height, 64u);
  EXPECT_TRUE(scene.point_lights.empty() && scene.spot_lights.empty() &&
              scene.directional_lights.empty());
  for (const Material& m : scene.materials) EXPECT_FALSE(m.is_emissive()) << m.name;

  // Materials by kind: the ground, the kinds themselves, and the kinds that carry a texture, a
  // normal or bump map or a cut-out.
  std::map<std::string, int> kinds;
  for (const Material& m : scene.materials) ++kinds[material_kind_name(m.kind)];
  const std::map<std::string, int> expected{
      {"diffuse", 4},        {"phong", 1},          {"mirror", 1},
      {"dielectric", 1},     {"roughconductor", 4}, {"roughdielectric", 1},
      {"thindielectric", 1}, {"plastic", 4},        {"metallic_roughness", 2}};
  EXPECT_EQ(kinds, expected);

  const auto& copper = params<RoughConductorMaterial>(material_named(scene, "copper"));
  EXPECT_EQ(copper.alpha_u.value, 0.f) << "a smooth conductor";
  const auto& gold = params<RoughConductorMaterial>(material_named(scene, "rough-gold"));
  EXPECT_EQ(gold.alpha_u.value, gold.alpha_v.value);
  EXPECT_GT(gold.alpha_u.value, 0.f);
  const auto& brushed = params<RoughConductorMaterial>(material_named(scene, "brushed"));
  EXPECT_NE(brushed.alpha_u.value, brushed.alpha_v.value) << "anisotropic";
  EXPECT_EQ(params<PlasticMaterial>(material_named(scene, "plastic")).alpha.value, 0.f);
  EXPECT_GT(params<PlasticMaterial>(material_named(scene, "rough-plastic")).alpha.value, 0.f);
  EXPECT_EQ(params<MetallicRoughnessMaterial>(material_named(scene, "gltf-metal")).metallic, 1.f);
  EXPECT_EQ(params<MetallicRoughnessMaterial>(material_named(scene, "gltf-dielectric")).metallic,
            0.f);
  EXPECT_TRUE(params<PlasticMaterial>(material_named(scene, "checkered"))
                  .diffuse_reflectance.is_textured());
  EXPECT_TRUE(material_named(scene, "hammered").bump_map);
  EXPECT_TRUE(material_named(scene, "pillows").normal_map);
  // The same cut-out sphere, one-sided (nothing seen through its holes on the inside) and
  // wrapped in "twosided" (its inside reflects).
  EXPECT_TRUE(material_named(scene, "cage").one_sided);
  EXPECT_FALSE(material_named(scene, "cage-twosided").one_sided);
  EXPECT_TRUE(material_named(scene, "cage").has_alpha());
  EXPECT_TRUE(material_named(scene, "cage-twosided").has_alpha());
  size_t textured = 0, mapped = 0, cut = 0;
  for (const Material& m : scene.materials) {
    textured += m.textured;
    mapped += m.has_surface_map();
    cut += m.has_alpha();
  }
  EXPECT_EQ(textured, 1u);
  EXPECT_EQ(mapped, 2u);
  EXPECT_EQ(cut, 2u);

  // A 6 x 3 grid: every material but the ground's on one sphere, every sphere on the ground.
  ASSERT_EQ(scene.spheres.size(), 18u);
  EXPECT_EQ(scene.materials.size(), 19u);
  std::set<uint32_t> used;
  for (const Sphere& s : scene.spheres) {
    used.insert(s.material);
    EXPECT_FLOAT_EQ(s.center.y, s.radius) << scene.materials[s.material].name;
  }
  EXPECT_EQ(used.size(), 18u);
  EXPECT_EQ(used.count(0u), 0u) << "the ground's material is the first";
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_NEAR(front_normal(scene.meshes[0], 0).y, 1.f, 1e-6f);
  const std::vector<fs::path> files{"dimples.png", "pillows.png", "sky.hdr"};
  std::vector<fs::path> referenced = scene.referenced;
  std::sort(referenced.begin(), referenced.end());
  EXPECT_EQ(referenced, files);
}

TEST(SceneBundled, EmbreeCornellMatchesTheTutorial) {
  const Scene scene = load_scene(bundled("embree-cornell"));
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  // One mesh per object that has faces: floor, ceiling, back, green and red walls, two blocks
  // (the light's and the front wall's faces are comments).
  ASSERT_EQ(scene.meshes.size(), 7u);
  size_t triangles = 0;
  for (const TriangleMesh& m : scene.meshes) triangles += m.triangle_count();
  EXPECT_EQ(triangles, 34u);  // 17 quads
  EXPECT_EQ(scene.meshes[0].triangle_count(), 6u);  // the floor: 3 quads
  EXPECT_EQ(scene.meshes[6].triangle_count(), 10u);  // the tall block
  EXPECT_EQ(scene.meshes[0].origin, "cornell_box.obj (object \"floor\")");
  EXPECT_EQ(scene.meshes[6].origin, "cornell_box.obj (object \"tall_block\")");
  EXPECT_TRUE(scene.spheres.empty());
  ASSERT_EQ(scene.point_lights.size(), 1u);
  EXPECT_EQ(scene.point_lights[0].position, Vec3(213.f, 300.f, 227.f));
  EXPECT_EQ(scene.point_lights[0].intensity, Vec3(100000.f));
  ASSERT_EQ(scene.materials.size(), 5u);
  for (const Material& m : scene.materials) {
    EXPECT_TRUE(std::holds_alternative<DiffuseMaterial>(m.kind)) << m.name;
    EXPECT_FALSE(m.is_emissive()) << m.name << ": Ka is not emission";
  }
  EXPECT_EQ(params<DiffuseMaterial>(material_named(scene, "cornell_box.obj:red")).albedo,
            Vec3(1.f, 0.f, 0.f));
  EXPECT_EQ(scene.film.width, 512u);
  EXPECT_EQ(scene.render.integrator, IntegratorType::kNee);
  EXPECT_EQ(scene.render.max_depth, 8u);
  const std::vector<fs::path> files{"cornell_box.obj", "cornell_box.mtl"};
  EXPECT_EQ(scene.referenced, files);
  EXPECT_EQ(scene.source, bundled("embree-cornell"));
  // The floor, the first face of the file, faces up.
  EXPECT_NEAR(front_normal(scene.meshes[0], 0).y, 1.f, 1e-6f);
}

// ---- what valid files turn into --------------------------------------------------------------

TEST(SceneParser, QuadFrontFaceIsEdge1CrossEdge2) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", scene_with(kMaterials + R"(,
  "shapes": [{"type": "quad", "corner": [1, 2, 3], "edge1": [2, 0, 0], "edge2": [0, 0, 3],
              "material": "m"}])"));
  const Scene scene = load_scene(file);
  ASSERT_EQ(scene.meshes.size(), 1u);
  const TriangleMesh& mesh = scene.meshes[0];
  EXPECT_EQ(mesh.origin, "shapes[0]");
  ASSERT_EQ(mesh.triangle_count(), 2u);
  for (size_t t = 0; t < 2; ++t) EXPECT_EQ(front_normal(mesh, t), Vec3(0.f, -1.f, 0.f));
  // (c, c+e1, c+e1+e2) and (c, c+e1+e2, c+e2)
  const std::vector<Vec3> corners{{1, 2, 3}, {3, 2, 3}, {3, 2, 6}, {1, 2, 3}, {3, 2, 6}, {1, 2, 6}};
  for (size_t k = 0; k < 6; ++k) EXPECT_EQ(mesh.positions[mesh.indices[k]], corners[k]);
}

TEST(SceneParser, DefaultsAndOrder) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", scene_with(R"("materials": {
    "z": {"type": "mirror"}, "a": {"type": "dielectric"}, "m": {"type": "diffuse"}},
  "shapes": [{"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "material": "m"}],
  "render": {"seed": 18446744073709551615})"));
  const Scene scene = load_scene(file);
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  ASSERT_EQ(scene.materials.size(), 3u);
  EXPECT_EQ(scene.materials[0].name, "z") << "materials keep the file's order";
  EXPECT_EQ(params<MirrorMaterial>(scene.materials[0]).reflectance, Vec3(1.f));
  EXPECT_EQ(params<DielectricMaterial>(scene.materials[1]).ior, 1.5f);
  EXPECT_EQ(params<DiffuseMaterial>(scene.materials[2]).albedo, Vec3(0.8f));
  EXPECT_EQ(scene.meshes.at(0).materials, std::vector<uint32_t>{2});
  EXPECT_EQ(scene.background, Vec3(0.f));
  EXPECT_EQ(scene.render.spp, 64u);
  EXPECT_EQ(scene.render.seed, UINT64_MAX);
  EXPECT_EQ(front_normal(scene.meshes[0], 0), Vec3(0.f, 0.f, 1.f));
}

TEST(SceneParser, UnknownKeysAreWarnings) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40, "fov": 3},
  "film": {"width": 16, "height": 16},
  "comment": {"deep": )" + std::string(60, '[') + std::string(60, ']') +
                                                    R"(},
  "materials": {"m": {"type": "diffuse", "ks": [0.5, 0.5, 0.5]}}
})");
  const Scene scene = load_scene(file);
  const std::string all = warnings_of(scene);
  ASSERT_EQ(warnings(scene).size(), 3u) << all;
  EXPECT_NE(all.find(file.string() + ": /camera/fov: unknown key"), std::string::npos) << all;
  EXPECT_NE(all.find(file.string() + ": /comment: unknown key"), std::string::npos) << all;
  EXPECT_NE(all.find(file.string() + ": /materials/m/ks: unknown key"), std::string::npos) << all;
}

TEST(SceneParser, ZeroAreaShapesAreDroppedWithAWarning) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", scene_with(kMaterials + R"(,
  "shapes": [
    {"type": "triangle", "vertices": [[0, 0, 0], [1, 1, 1], [2, 2, 2]], "material": "m"},
    {"type": "quad", "corner": [0, 0, 0], "edge1": [1, 0, 0], "edge2": [2, 0, 0], "material": "m"},
    {"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "material": "m"}])"));
  const Scene scene = load_scene(file);
  ASSERT_EQ(warnings(scene).size(), 2u) << warnings_of(scene);
  EXPECT_NE(warnings(scene)[0].find("/shapes/0: "), std::string::npos) << warnings(scene)[0];
  EXPECT_NE(warnings(scene)[1].find("/shapes/1: "), std::string::npos) << warnings(scene)[1];
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].origin, "shapes[2]");
}

TEST(SceneParser, ObjFacesAndMtlMaterials) {
  TempDir dir;
  dir.write("models/m.mtl", R"(# every mapping rule once
newmtl lamp
Kd 0.5 0.5 0.5
Ke 4 3 2
newmtl glass
illum 7
Ni 1.33
Tf 0.9 1 0.9
newmtl chrome
illum 3
Ks 0.8 0.8 0.8
newmtl plastic
Kd 0.8 0.2 0.2
Ks 0.5 0.5 0.5
Ns 50
newmtl clay
Kd 0.3 0.4 0.5
Ka 1 1 1
newmtl water
Ni 1.33
d 0.5
)");
  const std::string faces = R"(mtllib m.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0.5 1.5 0
v 0 1 0
f 1 2 3
usemtl lamp
f 1 2 3 4 5
usemtl glass
f -5/1 -4 -3
usemtl chrome
f 1 2 3
usemtl plastic
f 1 2 3
usemtl clay
f 1 2 3
usemtl water
f 1 2 3
)";
  dir.write("models/m.obj", faces);
  const fs::path file = dir.write("scene.json", scene_with(R"("shapes": [
    {"type": "mesh", "file": "models/m.obj"}])"));
  expect_error(file, {"m.obj:11: ", "texture coordinate index 1 is out of range"});
  dir.write("models/m.obj", "vt 0 0\n" + faces);
  const Scene scene = load_scene(file);
  const std::string all = warnings_of(scene);
  ASSERT_EQ(warnings(scene).size(), 1u) << all;
  EXPECT_NE(all.find("Kd + Ks exceeds 1"), std::string::npos) << all;
  EXPECT_NE(all.find("m.mtl:12"), std::string::npos) << all;

  ASSERT_EQ(scene.meshes.size(), 1u);
  const TriangleMesh& mesh = scene.meshes[0];
  EXPECT_EQ(mesh.origin, "models/m.obj");
  EXPECT_EQ(mesh.triangle_count(), 9u);  // the pentagon is a fan of 3
  const std::vector<fs::path> files{"models/m.obj", "models/m.mtl"};
  EXPECT_EQ(scene.referenced, files);
  ASSERT_EQ(scene.materials.size(), 7u);  // 6 from the MTL and a default for the first face

  const Material& lamp = material_named(scene, "models/m.obj:lamp");
  EXPECT_TRUE(std::holds_alternative<DiffuseMaterial>(lamp.kind));
  EXPECT_EQ(lamp.emission, Vec3(4.f, 3.f, 2.f));
  const auto& glass = params<DielectricMaterial>(material_named(scene, "models/m.obj:glass"));
  EXPECT_FLOAT_EQ(glass.ior, 1.33f);
  EXPECT_EQ(glass.tint, Vec3(0.9f, 1.f, 0.9f));
  const auto& chrome = params<MirrorMaterial>(material_named(scene, "models/m.obj:chrome"));
  EXPECT_EQ(chrome.reflectance, Vec3(0.8f));
  const auto& plastic = params<PhongMaterial>(material_named(scene, "models/m.obj:plastic"));
  EXPECT_EQ(plastic.exponent, 50.f);
  EXPECT_LE(max_component(plastic.kd + plastic.ks), 1.f + 1e-6f);
  EXPECT_FLOAT_EQ(plastic.kd.x / plastic.ks.x, 0.8f / 0.5f) << "scaled together";
  EXPECT_EQ(params<DiffuseMaterial>(material_named(scene, "models/m.obj:clay")).albedo,
            Vec3(0.3f, 0.4f, 0.5f));
  EXPECT_TRUE(
      std::holds_alternative<DielectricMaterial>(material_named(scene, "models/m.obj:water").kind));
  EXPECT_TRUE(
      std::holds_alternative<DiffuseMaterial>(material_named(scene, "models/m.obj:default").kind));

  const std::vector<std::string> per_triangle{"default", "lamp",    "lamp", "lamp", "glass",
                                              "chrome",  "plastic", "clay", "water"};
  for (size_t t = 0; t < 9; ++t) {
    EXPECT_EQ(scene.materials[mesh.materials[t]].name, "models/m.obj:" + per_triangle[t]);
  }
}

TEST(SceneParser, MeshMaterialOverridesTheMtl) {
  TempDir dir;
  dir.write("m.mtl", "newmtl shiny\nKs 1 1 1\n");
  dir.write("m.obj", "mtllib m.mtl\nusemtl shiny\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const fs::path file = dir.write("scene.json", scene_with(kMaterials + R"(,
  "shapes": [{"type": "mesh", "file": "./m.obj", "material": "m"}])"));
  const Scene scene = load_scene(file);
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  ASSERT_EQ(scene.materials.size(), 1u);
  EXPECT_EQ(scene.meshes.at(0).materials, std::vector<uint32_t>{0});
  EXPECT_EQ(scene.referenced.size(), 2u);
}

TEST(SceneParser, AUsemtlBeforeAnyMtllibGetsTheDefaultMaterial) {
  TempDir dir;
  dir.write("m.mtl", "newmtl a\nKd 0.5 0.5 0.5\n");
  dir.write("m.obj",
            "usemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nmtllib m.mtl\nusemtl a\nf 1 2 3\n");
  const fs::path file = dir.write("scene.json", scene_with(R"(
  "shapes": [{"type": "mesh", "file": "m.obj"}])"));
  const Scene scene = load_scene(file);
  ASSERT_EQ(warnings(scene).size(), 1u) << warnings_of(scene);
  EXPECT_NE(warnings(scene)[0].find("m.obj:1: usemtl \"a\" comes before any mtllib"),
            std::string::npos)
      << warnings(scene)[0];
  const TriangleMesh& mesh = scene.meshes.at(0);
  ASSERT_EQ(mesh.triangle_count(), 2u);
  EXPECT_EQ(scene.materials[mesh.materials[0]].name, "m.obj:default");
  EXPECT_EQ(scene.materials[mesh.materials[1]].name, "m.obj:a");
}

// ---- errors in the JSON ----------------------------------------------------------------------

TEST(SceneErrors, UnknownMaterialType) {
  expect_scene_error(R"("materials": {"m": {"type": "velvet"}})",
                     {"/materials/m/type", "\"velvet\"", "diffuse, phong, mirror, dielectric"});
}

TEST(SceneErrors, StringInAVector) {
  expect_scene_error(R"("materials": {"red": {"type": "diffuse", "albedo": [0.5, "x", 0.5]}})",
                     {": /materials/red/albedo/1: expected a number, got string \"x\""});
}

TEST(SceneErrors, NanInAVector) {
  expect_scene_error(kMaterials + R"(, "shapes": [{"type": "sphere", "center": ["NaN", 0, 0],
                     "radius": 1, "material": "m"}])",
                     {"/shapes/0/center/0", "expected a number"});
  expect_scene_error(kMaterials + R"(, "shapes": [{"type": "sphere", "center": [0, 0, 1e31],
                     "radius": 1, "material": "m"}])",
                     {"/shapes/0/center/2", "out of range"});
  expect_scene_error(R"("background": [0, 0])", {"/background", "3 numbers"});
  // JSON has no NaN or infinity: such files are not JSON at all.
  expect_scene_error(R"("background": [NaN, 0, 0])", {"invalid JSON", "line 4"});
  expect_scene_error(R"("background": [1e400, 0, 0])", {"invalid JSON", "1e400"});
}

TEST(SceneErrors, BadNumbers) {
  expect_scene_error(kMaterials + R"(, "shapes": [{"type": "sphere", "center": [0, 0, 0],
                     "radius": -1, "material": "m"}])",
                     {"/shapes/0/radius", "positive"});
  expect_scene_error(R"("materials": {"m": {"type": "diffuse", "albedo": [0.5, 1.5, 0.5]}})",
                     {"/materials/m/albedo/1", "[0, 1]"});
  expect_scene_error(R"("materials": {"m": {"type": "phong", "kd": [0.5, 0.5, 0.5],
                     "ks": [0.6, 0.1, 0.1], "exponent": 10}})",
                     {"/materials/m", "energy"});
  expect_scene_error(R"("materials": {"m": {"type": "dielectric", "ior": 0}})",
                     {"/materials/m/ior", "positive"});
  expect_scene_error(R"("materials": {"m": {"type": "diffuse", "emission": [1, -1, 1]}})",
                     {"/materials/m/emission/1", "negative"});
  expect_scene_error(R"("lights": [{"type": "point", "position": [0, 0, 0], "intensity": 5}])",
                     {"/lights/0/intensity", "expected an array"});
  expect_scene_error(R"("render": {"spp": 0})", {"/render/spp", "from 1 to 16777216"});
  expect_scene_error(R"("render": {"max_depth": 2.5})", {"/render/max_depth", "integer"});
  expect_scene_error(R"("render": {"seed": -1})", {"/render/seed", "unsigned"});
  expect_scene_error(R"("render": {"integrator": "bdpt"})", {"/render/integrator", "\"bdpt\""});
}

TEST(SceneErrors, UnknownMaterialName) {
  expect_scene_error(kMaterials + R"(, "shapes": [{"type": "sphere", "center": [0, 0, 0],
                     "radius": 1, "material": "nosuch"}])",
                     {"/shapes/0/material", "\"nosuch\"", "defined: m"});
}

TEST(SceneErrors, UnknownShapeAndLightTypes) {
  expect_scene_error(R"("shapes": [{"type": "cube"}])", {"/shapes/0/type", "\"cube\""});
  expect_scene_error(R"("shapes": [{"radius": 1}])", {"/shapes/0", "missing key \"type\""});
  expect_scene_error(R"("lights": [{"type": "area"}])", {"/lights/0/type", "\"area\""});
}

TEST(SceneErrors, FilmTooLarge) {
  expect_scene_error(R"("film": {"width": 16384, "height": 16384})", {"/film", "2^26"});
  expect_scene_error(R"("film": {"width": 100000000000, "height": 1})", {"/film/width", "16384"});
}

/// The film's filter read from `film` (the film object's members after width and height).
PixelFilter filter_of(const std::string& film) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
  "film": {"width": 16, "height": 16)" + film + R"(}
})");
  const Scene scene = load_scene(file);
  EXPECT_TRUE(warnings(scene).empty()) << warnings_of(scene);
  return scene.filter;
}

TEST(SceneParser, FilmFiltersByNameOrWithTheirParameters) {
  EXPECT_TRUE(filter_of("").pixel_box()) << "no filter: each pixel's own box";
  EXPECT_TRUE(filter_of("").sample_border);
  const PixelFilter gaussian = filter_of(R"(, "filter": "gaussian")");
  EXPECT_EQ(gaussian.type, FilterType::kGaussian);
  EXPECT_EQ(gaussian.stddev, 0.5f);
  EXPECT_EQ(gaussian.radius, 2.f) << "four standard deviations";
  EXPECT_EQ(gaussian.steps, 0u) << "the filter as defined, not tabulated";
  const PixelFilter narrow =
      filter_of(R"(, "filter": {"type": "gaussian", "stddev": 0.25}, "sample_border": false)");
  EXPECT_EQ(narrow.radius, 1.f);
  EXPECT_FALSE(narrow.sample_border);
  const PixelFilter tent = filter_of(R"(, "filter": {"type": "tent", "radius": 1.5})");
  EXPECT_EQ(tent.type, FilterType::kTent);
  EXPECT_EQ(tent.radius, 1.5f);
  EXPECT_FALSE(filter_of(R"(, "filter": {"type": "box", "radius": 1})").pixel_box());
  const PixelFilter mitchell = filter_of(R"(, "filter": {"type": "mitchell", "b": 0.5})");
  EXPECT_EQ(mitchell.type, FilterType::kMitchell);
  EXPECT_EQ(mitchell.b, 0.5f);
  EXPECT_EQ(mitchell.c, 1.f / 3.f);
  EXPECT_EQ(mitchell.radius, 2.f);
  const PixelFilter catmull_rom = filter_of(R"(, "filter": "catmull-rom")");
  EXPECT_EQ(catmull_rom.b, 0.f);
  EXPECT_EQ(catmull_rom.c, 0.5f);
  EXPECT_EQ(filter_of(R"(, "filter": "lanczos")").radius, 3.f);
  EXPECT_EQ(filter_of(R"(, "filter": {"type": "lanczos", "lobes": 2})").radius, 2.f);
  const PixelFilter bh = filter_of(R"(, "filter": "blackman-harris")");
  EXPECT_EQ(bh.type, FilterType::kBlackmanHarris);
  EXPECT_EQ(bh.radius, 0.75f) << "Cycles' width of 1.5 pixels";
  EXPECT_EQ(filter_of(R"(, "filter": {"type": "blackman-harris", "width": 3})").radius, 1.5f);
}

TEST(SceneErrors, BadFilmFilters) {
  const auto film = [](const std::string& members) {
    return R"("film": {"width": 16, "height": 16, )" + members + "}";
  };
  expect_scene_error(film(R"("filter": "sinc")"),
                     {"/film/filter", "unknown filter \"sinc\"", "gaussian"});
  expect_scene_error(film(R"("filter": {"radius": 1})"), {"/film/filter", "missing key \"type\""});
  expect_scene_error(film(R"("filter": {"type": "tent", "radius": 0})"),
                     {"/film/filter/radius", "radius must lie in [0.001, 8]"});
  expect_scene_error(film(R"("filter": {"type": "tent", "radius": 9})"),
                     {"/film/filter/radius", "[0.001, 8]"});
  expect_scene_error(film(R"("filter": {"type": "gaussian", "stddev": 3})"),
                     {"/film/filter/stddev", "[0.00025, 2]"});
  expect_scene_error(film(R"("filter": {"type": "mitchell", "c": -1})"),
                     {"/film/filter/c", "[0, 1]"});
  // Half of the smallest float is 0: the width is checked, not only its half.
  expect_scene_error(film(R"("filter": {"type": "blackman-harris", "width": 1e-45})"),
                     {"/film/filter/width", "[0.002, 16]"});
  expect_scene_error(film(R"("filter": {"type": "lanczos", "lobes": 0})"), {"/film/filter/lobes"});
  expect_scene_error(film(R"("filter": 3)"), {"/film/filter", "expected a string"});
  expect_scene_error(film(R"("filter": "box", "sample_border": "no")"), {"/film/sample_border"});
  TempDir dir;  // Mitsuba's Gaussian has no radius of its own: a "radius" is an unknown key
  const fs::path file = dir.write("scene.json", R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
  "film": {"width": 16, "height": 16, "filter": {"type": "gaussian", "radius": 3}}
})");
  const Scene scene = load_scene(file);
  EXPECT_NE(warnings_of(scene).find("/film/filter/radius: unknown key"), std::string::npos)
      << warnings_of(scene);
  EXPECT_EQ(scene.filter.radius, 2.f);
}

TEST(SceneErrors, FormatTooNew) {
  expect_scene_error(R"("format": 2)", {"/format", "format 2", "format 1"});
}

TEST(SceneErrors, BadCamera) {
  TempDir dir;
  const auto camera = [&](const std::string& camera_json) {
    return dir.write("scene.json",
                     "{\"camera\": " + camera_json + ", \"film\": {\"width\": 1, \"height\": 1}}");
  };
  expect_error(camera(R"({"eye": [1, 2, 3], "look_at": [1, 2, 3], "fov_y": 40})"),
               {"/camera/look_at", "equals eye"});
  expect_error(camera(R"({"eye": [0, 0, 0], "look_at": [0, 5, 0], "up": [0, 2, 0], "fov_y": 40})"),
               {"/camera/up", "parallel"});
  expect_error(camera(R"({"eye": [0, 0, 0], "look_at": [0, 0, 1], "fov_y": 180})"),
               {"/camera/fov_y", "(0, 180)"});
  expect_error(camera(R"({"type": "fisheye", "eye": [0, 0, 0], "look_at": [0, 0, 1]})"),
               {"/camera/type", "\"fisheye\"", "perspective", "orthographic"});
  expect_error(camera(R"({"type": "orthographic", "eye": [0, 0, 0], "look_at": [0, 0, 1],
                          "view_height": -1})"),
               {"/camera/view_height"});
  expect_error(camera(R"({"type": "orthographic", "eye": [0, 0, 0], "look_at": [0, 0, 1],
                          "view_height": 1e-50})"),
               {"/camera/view_height", "positive"});
  expect_error(camera(R"({"eye": [0, 0, 0], "look_at": [0, 0, 1]})"),
               {"/camera", "missing key \"fov_y\""});
  expect_error(dir.write("scene.json", R"({"film": {"width": 1, "height": 1}})"),
               {"(top level)", "missing key \"camera\""});
}

TEST(SceneErrors, MalformedJson) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", scene_with(kMaterials).substr(0, 100));
  expect_error(file, {file.string() + ": invalid JSON (byte ", "line 3"});
  expect_error(dir.write("scene.json", "[1, 2]"), {"(top level)", "expected an object"});
  expect_error(dir.write("scene.json", ""), {"invalid JSON"});
  expect_error(dir.write("scene.json", "{\"camera\": \"\xff\xfe\"}"), {"invalid JSON", "UTF-8"});
}

TEST(SceneErrors, DeepNesting) {
  TempDir dir;
  const std::string deep = std::string(100000, '[') + std::string(100000, ']');
  const fs::path file = dir.write("scene.json", scene_with("\"comment\": " + deep));
  expect_error(file, {file.string(), "nested more than 64 levels"});
  expect_error(dir.write("scene.json", deep), {"nested more than 64 levels"});
  expect_error(dir.write("scene.json", std::string(100000, '{')), {"invalid JSON"});
}

TEST(SceneErrors, UnreadableFiles) {
  TempDir dir;
  expect_error(dir.path() / "absent.json", {"absent.json", "not found"});
  expect_error(dir.path(), {dir.path().string(), "not a regular file"});
}

// ---- errors in paths and mesh files ----------------------------------------------------------

TEST(SceneErrors, MissingMeshFile) {
  expect_scene_error(R"("shapes": [{"type": "mesh", "file": "missing.obj"}])",
                     {"/shapes/0/file", "\"missing.obj\"", "not found"});
}

TEST(SceneErrors, PathsOutsideTheSceneFolder) {
  TempDir dir;
  dir.write("x.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const auto mesh = [&](const std::string& path) {
    return dir.write("sub/scene.json",
                     scene_with(R"("shapes": [{"type": "mesh", "file": ")" + path + "\"}]"));
  };
  expect_error(mesh("../x.obj"), {"sub/scene.json: /shapes/0/file", "leaves the scene's folder"});
  expect_error(mesh("a/../../x.obj"), {"/shapes/0/file", "leaves the scene's folder"});
  expect_error(mesh((dir.path() / "x.obj").string()), {"/shapes/0/file", "absolute"});
  expect_error(mesh(""), {"/shapes/0/file", "empty"});
  dir.write("sub/y.obj", "mtllib ../evil.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_error(mesh("y.obj"), {"y.obj:1: mtllib \"../evil.mtl\"", "leaves the scene's folder"});
}

/// Expects that a mesh file with `obj` content fails with "m.obj:LINE" and `what`.
void expect_obj_error(const std::string& obj, size_t line, const std::string& what) {
  TempDir dir;
  dir.write("m.obj", obj);
  dir.write("m.mtl", "newmtl a\nKd 0.5 0.5 0.5\n");
  const fs::path file = dir.write("scene.json", scene_with(R"("shapes": [
    {"type": "mesh", "file": "m.obj"}])"));
  expect_error(file, {(dir.path() / "m.obj").string() + ":" + std::to_string(line) + ": ", what});
}

TEST(SceneErrors, TruncatedObj) {
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2", 4, "at least 3");
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1", 3, "expected 3 coordinates");
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0.\nf 1 2 3/", 4, "malformed face vertex");
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl", 5, "usemtl without");
}

TEST(SceneErrors, ObjIndexOutOfRange) {
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "index 4 is out of range");
  expect_obj_error("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n", 3, "index 3 is out of range");
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", 4, "index -4 is out of range");
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0 is invalid");
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2 3\n", 4, "normal index 1 is out of range");
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n", 4, "malformed");
}

TEST(SceneErrors, ObjNonUtf8) {
  expect_obj_error("# ok\no caf\xc3\xa9\no \xff\xfe\n", 3, "invalid UTF-8 byte 0xFF");
  expect_obj_error(std::string("v 0 0 0\nv 1 0 0\x00\n", 17), 2, "NUL byte");
  expect_obj_error("v 0 0 0\nv nan 0 0\n", 2, "not a finite number");
}

TEST(SceneErrors, ObjMaterials) {
  expect_obj_error("mtllib m.mtl\nusemtl b\n", 2, "usemtl \"b\": no material");
  expect_obj_error("\nmtllib other.mtl\n", 2, "mtllib \"other.mtl\": file not found");
  TempDir dir;
  dir.write("m.obj", "mtllib m.mtl\n");
  dir.write("m.mtl", "newmtl a\nKd 0.5 \xc0\xaf 0.5\n");
  const fs::path file = dir.write("scene.json", scene_with(R"("shapes": [
    {"type": "mesh", "file": "m.obj"}])"));
  expect_error(file, {"m.mtl:2: ", "UTF-8"});
  dir.write("m.mtl", "newmtl a\nKd 0.5 0.5\n");
  expect_error(file, {"m.mtl:2: ", "3 numbers"});
  dir.write("m.mtl", "newmtl a\nKe -1 0 0\n");
  expect_error(file, {"m.mtl:1: ", "Ke must not be negative"});
  dir.write("m.mtl", "newmtl a\nillum 4\nNi 0\n");
  expect_error(file, {"m.mtl:1: ", "Ni must be positive"});
}

// ---- robustness ------------------------------------------------------------------------------

/// Loads `file`; anything but success or a SceneError fails the test.
void load_or_scene_error(const fs::path& file, const std::string& what) {
  try {
    (void)load_scene(file);
  } catch (const SceneError&) {
  } catch (const std::exception& e) {
    ADD_FAILURE() << what << ": not a SceneError: " << e.what();
  }
}

TEST(SceneRobustness, EveryTruncationAndRandomCorruption) {
  TempDir dir;
  const std::string scene = read_file(bundled("cornell-box"));
  const std::string obj = read_file(bundled("embree-cornell").parent_path() / "cornell_box.obj");
  const std::string mtl = read_file(bundled("embree-cornell").parent_path() / "cornell_box.mtl");
  const fs::path embree = dir.write("scene.json", read_file(bundled("embree-cornell")));
  dir.write("cornell_box.mtl", mtl);
  const fs::path cornell = dir.write("cornell.json", "");

  for (size_t n = 0; n < scene.size(); n += 7) {
    dir.write("cornell.json", scene.substr(0, n));
    load_or_scene_error(cornell, "scene cut at " + std::to_string(n));
  }
  for (size_t n = 0; n < obj.size(); n += 5) {
    dir.write("cornell_box.obj", obj.substr(0, n));
    load_or_scene_error(embree, "OBJ cut at " + std::to_string(n));
  }
  std::mt19937 random(12345);  // fixed seed: the same corruptions every run
  const std::string alphabet = "0123456789-+.eE/ \n[]{}\",:#fvnul\xff\x80";
  for (int trial = 0; trial < 300; ++trial) {
    std::string s = scene;
    std::string o = obj;
    std::string m = mtl;
    for (int k = 0; k < 4; ++k) {
      s[random() % s.size()] = alphabet[random() % alphabet.size()];
      o[random() % o.size()] = alphabet[random() % alphabet.size()];
      m[random() % m.size()] = alphabet[random() % alphabet.size()];
    }
    dir.write("cornell.json", s);
    dir.write("cornell_box.obj", o);
    dir.write("cornell_box.mtl", m);
    load_or_scene_error(cornell, "corrupted scene, trial " + std::to_string(trial));
    load_or_scene_error(embree, "corrupted OBJ/MTL, trial " + std::to_string(trial));
  }
}

}  // namespace
}  // namespace rayfarm
