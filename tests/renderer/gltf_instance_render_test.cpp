// A glTF mesh placed by two nodes becomes one group and two instances; it must render as the
// same file with the mesh written out twice (two world meshes), within the noise. Emissive
// meshes used twice are placed as world triangles by the renderer, and light the same way.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/scene/parser.h"
#include "tests/support/gltf_builder.h"
#include "tests/support/temp_dir.h"
#include "tests/renderer/mc_stats.h"
#include "renderer/scene_data.h"

namespace rayfarm {
namespace {

using testing::GltfBuilder;
using Json = nlohmann::json;

constexpr double kPi = 3.14159265358979323846;

/// A floor, a panel placed by two nodes (one mirrored) and a lamp placed by two nodes, seen by
/// a camera. With `duplicate`, the second node of each pair places its own copy of the mesh.
GltfBuilder two_of_each(bool duplicate) {
  GltfBuilder b;
  const auto pbr = [](Json color, double roughness) {
    return Json{
        {"pbrMetallicRoughness",
         {{"baseColorFactor", color}, {"metallicFactor", 0.0}, {"roughnessFactor", roughness}}}};
  };
  const int floor_paint = b.push("materials", pbr({0.7, 0.7, 0.7, 1.0}, 1.0));
  const int panel_paint = b.push("materials", pbr({0.8, 0.5, 0.2, 1.0}, 0.4));
  Json lamp_paint = pbr({0.0, 0.0, 0.0, 1.0}, 1.0);
  lamp_paint["emissiveFactor"] = {1.0, 0.9, 0.8};
  lamp_paint["doubleSided"] = true;
  const int lamp_material = b.push("materials", lamp_paint);
  const int floor = b.add_quad(floor_paint);
  const int panel = b.add_quad(panel_paint);
  const int lamp = b.add_quad(lamp_material);
  const int panel2 = duplicate ? b.push("meshes", b.doc["meshes"][panel]) : panel;
  const int lamp2 = duplicate ? b.push("meshes", b.doc["meshes"][lamp]) : lamp;
  const double s = std::sin(kPi / 12), c = std::cos(kPi / 12);  // 30 degrees about +y
  const double ls = std::sin(kPi / 4), lc = std::cos(kPi / 4);  // 90 degrees about +x
  b.push("nodes", {{"mesh", floor}, {"translation", {-1.5, -1.5, -0.5}}, {"scale", {4, 4, 4}}});
  b.push("nodes", {{"mesh", panel},
                   {"translation", {-0.6, 0.0, 0.0}},
                   {"rotation", {0, s, 0, c}},
                   {"scale", {0.5, 0.7, 0.5}}});
  b.push("nodes", {{"mesh", panel2},
                   {"translation", {1.4, 0.2, 0.1}},
                   {"rotation", {0, -s, 0, c}},
                   {"scale", {-0.6, 0.5, 0.5}}});  // a mirror
  b.push("nodes",
         {{"mesh", lamp}, {"translation", {-1.8, 1.6, 1.2}}, {"rotation", {ls, 0, 0, lc}}});
  b.push("nodes",
         {{"mesh", lamp2}, {"translation", {1.8, 1.6, 1.2}}, {"rotation", {ls, 0, 0, lc}}});
  b.push("cameras", {{"type", "perspective"},
                     {"perspective", {{"yfov", 0.9}, {"aspectRatio", 4.0 / 3.0}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 0}, {"translation", {0.5, 0.5, 3.0}}});
  b.doc["scenes"] = {{{"nodes", {0, 1, 2, 3, 4, 5}}}};
  b.doc["scene"] = 0;
  return b;
}

Scene load(testing::TempDir& dir, bool duplicate) {
  const std::string name = duplicate ? "twice.glb" : "shared.glb";
  Scene scene = load_scene(dir.write(name, two_of_each(duplicate).glb()));
  scene.film = {32, 24};
  scene.render.max_depth = 4;
  return scene;
}

TEST(GltfInstanceRender, AMeshUsedTwiceRendersAsTwoCopies) {
  testing::TempDir dir;
  const Scene shared = load(dir, false), twice = load(dir, true);
  ASSERT_EQ(shared.groups.size(), 2u);     // the panel and the lamp
  ASSERT_EQ(shared.instances.size(), 4u);  // two of each
  EXPECT_EQ(shared.meshes.size(), 1u);     // the floor
  EXPECT_TRUE(twice.groups.empty());
  EXPECT_EQ(twice.meshes.size(), 5u);
  // The lamp's instances become world triangles for the area lights; the panel's stay shared.
  const SceneData data(shared);
  EXPECT_EQ(data.instances(), 2u);
  EXPECT_EQ(data.flattened_instances(), 2u);
  constexpr uint32_t kBlock = 4;
  const IntegratorType integrators[] = {IntegratorType::kNee, IntegratorType::kMis};
  const size_t family = std::size(integrators) * (32 / kBlock) * (24 / kBlock) * 3;
  for (const IntegratorType integrator : integrators) {
    const testing::BlockStats a = testing::render_blocks(shared, integrator, 256, 1, kBlock);
    const testing::BlockStats b = testing::render_blocks(twice, integrator, 256, 2, kBlock);
    testing::expect_same_within_noise(a, b, integrator_name(integrator), family);
  }
}

/// A grey floor and a panel placed by two nodes under a lamp. With `colours`, the panel's mesh has
/// COLOR_0 = `colour` at every vertex over a base colour `base`; without, its base colour is
/// base x colour and it has no COLOR_0.
GltfBuilder coloured_panel(bool colours, const Json& base, const Json& colour) {
  GltfBuilder b;
  const auto pbr = [](Json rgb, double roughness) {
    return Json{{"pbrMetallicRoughness",
                 {{"baseColorFactor", {rgb[0], rgb[1], rgb[2], 1.0}},
                  {"metallicFactor", 0.0},
                  {"roughnessFactor", roughness}}}};
  };
  Json product = Json::array();
  for (int i = 0; i < 3; ++i) product.push_back(base[i].get<double>() * colour[i].get<double>());
  const int floor_paint = b.push("materials", pbr({0.7, 0.7, 0.7}, 1.0));
  const int panel_paint = b.push("materials", pbr(colours ? base : product, 0.5));
  Json lamp_paint = pbr({0.0, 0.0, 0.0}, 1.0);
  lamp_paint["emissiveFactor"] = {1.0, 1.0, 1.0};
  lamp_paint["doubleSided"] = true;
  const int lamp_material = b.push("materials", lamp_paint);
  const int floor = b.add_quad(floor_paint);
  const int panel = b.add_quad(panel_paint);
  const int lamp = b.add_quad(lamp_material);
  if (colours) {
    std::vector<float> rgba;
    for (int v = 0; v < 4; ++v)
      rgba.insert(rgba.end(),
                  {colour[0].get<float>(), colour[1].get<float>(), colour[2].get<float>(), 1.f});
    b.doc["meshes"][panel]["primitives"][0]["attributes"]["COLOR_0"] = b.add_floats(rgba, "VEC4");
  }
  const double ls = std::sin(kPi / 4), lc = std::cos(kPi / 4);  // 90 degrees about +x
  b.push("nodes", {{"mesh", floor}, {"translation", {-1.5, -1.5, -0.5}}, {"scale", {4, 4, 4}}});
  b.push("nodes", {{"mesh", panel}, {"translation", {-1.0, -0.2, 0.0}}, {"scale", {0.8, 1, 1}}});
  b.push("nodes", {{"mesh", panel}, {"translation", {0.4, 0.1, 0.2}}, {"scale", {0.7, 0.8, 1}}});
  b.push("nodes",
         {{"mesh", lamp}, {"translation", {-0.5, 1.6, 1.2}}, {"rotation", {ls, 0, 0, lc}}});
  b.push("cameras", {{"type", "perspective"},
                     {"perspective", {{"yfov", 0.9}, {"aspectRatio", 4.0 / 3.0}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 0}, {"translation", {0.0, 0.4, 3.0}}});
  b.doc["scenes"] = {{{"nodes", {0, 1, 2, 3, 4}}}};
  b.doc["scene"] = 0;
  return b;
}

// glTF's COLOR_0 multiplies the base colour: a mesh coloured c over a base b renders as the same
// mesh of base colour b x c, here through two instances of one group, within the noise
// (expect_same_within_noise: per-block z-tests, Bonferroni-corrected over every block, channel
// and integrator).
TEST(GltfInstanceRender, VertexColoursMultiplyTheBaseColour) {
  testing::TempDir dir;
  const Json base = {0.9, 0.8, 0.7}, colour = {0.2, 0.9, 0.5};
  auto load_one = [&](bool colours) {
    Scene scene = load_scene(dir.write(colours ? "coloured.glb" : "product.glb",
                                       coloured_panel(colours, base, colour).glb()));
    scene.film = {32, 24};
    scene.render.max_depth = 4;
    return scene;
  };
  const Scene coloured = load_one(true), plain = load_one(false);
  ASSERT_EQ(coloured.groups.size(), 1u);  // the panel, placed twice
  ASSERT_EQ(coloured.groups[0].meshes.size(), 1u);
  EXPECT_EQ(coloured.groups[0].meshes[0].colours.size(), 4u);
  EXPECT_TRUE(coloured.materials[1].vertex_colours);
  EXPECT_FALSE(plain.materials[1].vertex_colours);
  constexpr uint32_t kBlock = 4;
  const IntegratorType integrators[] = {IntegratorType::kNee, IntegratorType::kMis};
  const size_t family = std::size(integrators) * (32 / kBlock) * (24 / kBlock) * 3;
  for (const IntegratorType integrator : integrators) {
    const testing::BlockStats a = testing::render_blocks(coloured, integrator, 256, 1, kBlock);
    const testing::BlockStats b = testing::render_blocks(plain, integrator, 256, 2, kBlock);
    testing::expect_same_within_noise(a, b, integrator_name(integrator), family);
  }
}

// The colour at a hit is the vertices' colours weighted by its barycentrics.
TEST(GltfInstanceRender, AVertexColourIsInterpolatedAtTheHit) {
  Scene scene;
  scene.materials.push_back(Material{});
  TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.indices = {0, 1, 2};
  mesh.materials = {0};
  mesh.colours = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  scene.meshes.push_back(mesh);
  scene.meshes.push_back(mesh);
  scene.meshes.back().colours.clear();
  const SceneData data(scene);
  RayHit hit;
  hit.geom = 0, hit.prim = 0, hit.u = 0.25f, hit.v = 0.5f;
  const Vec3 c = data.vertex_colour(hit);
  EXPECT_FLOAT_EQ(c.x, 0.25f);
  EXPECT_FLOAT_EQ(c.y, 0.25f);
  EXPECT_FLOAT_EQ(c.z, 0.5f);
  hit.geom = 1;  // no colours: white
  EXPECT_EQ(data.vertex_colour(hit), Vec3(1.f));
}

}  // namespace
}  // namespace rayfarm
