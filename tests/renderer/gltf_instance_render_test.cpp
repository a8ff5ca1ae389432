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

}  // namespace
}  // namespace rayfarm
