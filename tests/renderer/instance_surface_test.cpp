// Instanced groups with the materials that need more than a normal: opacity cut-outs, normal and
// bump maps, anisotropic roughness. Each renders as the same group placed as world meshes by
// place_mesh (flatten_instances) within the noise, under a rotation, a non-uniform scale and a
// mirror; and a ray through a cut-out texel of an instance passes, exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "common/image/png.h"
#include "common/scene/instances.h"
#include "tests/renderer/mc_stats.h"
#include "tests/renderer/surface_scenes.h"
#include "renderer/scene_data.h"

namespace rayfarm {
namespace {

using testing::scene_from;

// Maps of smoothly varying slopes, so that a wrong tangent, bitangent or derivative moves the
// shading of many pixels: normals tilted along both axes, and a height of two waves.
void write_maps(testing::TempDir& dir) {
  constexpr int kSize = 16;
  std::vector<uint8_t> normals, heights;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const double a = 2.0 * 3.14159265358979 * x / kSize, b = 2.0 * 3.14159265358979 * y / kSize;
      const double nx = 0.6 * std::sin(a), ny = 0.5 * std::cos(b);
      const double nz = std::sqrt(std::max(0.05, 1.0 - nx * nx - ny * ny));
      for (const double c : {nx, ny, nz}) normals.push_back(uint8_t(std::lround(127.5 * (c + 1))));
      const double h = 0.5 + 0.25 * std::sin(a) + 0.25 * std::sin(b + 0.5 * a);
      for (int c = 0; c < 3; ++c) heights.push_back(uint8_t(std::lround(255 * h)));
    }
  }
  write_png_rgb8(dir.path() / "normals.png", normals, kSize, kSize);
  write_png_rgb8(dir.path() / "height.png", heights, kSize, kSize);
}

// A group of two quads at an angle, placed three times: rotated, stretched unevenly, mirrored;
// over a white floor in "shapes", under a sky and a point light. `material` is the group's.
Scene instanced_scene(testing::TempDir& dir, const std::string& material) {
  Scene s = scene_from(dir, R"(
    "camera": {"eye": [0, 1.5, 5], "look_at": [0, 0, 0], "fov_y": 45},
    "film": {"width": 32, "height": 24},
    "textures": {
      "check": {"type": "checkerboard", "color0": [0, 0, 0], "color1": [1, 1, 1]},
      "normals": {"type": "image", "file": "normals.png", "color_space": "linear"},
      "height": {"type": "image", "file": "height.png"}},
    "materials": {"floor": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]}, "m": )" +
                                material + R"(},
    "groups": {"g": [
      {"type": "quad", "corner": [-0.6, -0.6, 0], "edge1": [1.2, 0, 0], "edge2": [0, 1.2, 0],
       "material": "m"},
      {"type": "quad", "corner": [-0.6, -0.6, 0.2], "edge1": [0, 0.3, 1], "edge2": [1.2, 0.2, 0],
       "material": "m"}]},
    "shapes": [
      {"type": "quad", "corner": [-4, -1, -4], "edge1": [0, 0, 8], "edge2": [8, 0, 0],
       "material": "floor"},
      {"type": "instance", "group": "g", "transform": [
        {"rotate": {"axis": [0.3, 1, 0.2], "angle": 35}}, {"translate": [-1.6, 0, 0]}]},
      {"type": "instance", "group": "g", "transform": [
        {"scale": [1.5, 0.6, 1.2]}, {"rotate": {"axis": [0, 1, 0], "angle": -20}},
        {"translate": [0.1, -0.2, 0.5]}]},
      {"type": "instance", "group": "g", "transform": [
        {"scale": [-1, 1.3, 1]}, {"rotate": {"axis": [1, 0, 0], "angle": -15}},
        {"translate": [1.6, 0.2, -0.3]}]}],
    "lights": [{"type": "point", "position": [2, 3, 3], "intensity": [6, 6, 6]}],
    "background": [0.5, 0.5, 0.5],
    "render": {"max_depth": 3})");
  // The second quad carries its own tangents, turned away from dp/du, so that both ways to a
  // tangent are placed: the mesh's (with its handedness) and the derivatives'.
  TriangleMesh& tilted = s.groups.at(0).meshes.at(1);
  tilted.tangents.assign(tilted.positions.size(), Vec4(0.8f, 0.f, -0.6f, -1.f));
  return s;
}

TEST(InstanceSurface, SurfaceFeaturesRenderAsThePlacedMeshes) {
  testing::TempDir dir;
  write_maps(dir);
  const std::pair<const char*, std::string> cases[] = {
      {"cut-out", R"({"type": "diffuse", "albedo": [0.8, 0.3, 0.2],
                      "opacity": {"texture": "check", "channel": "r"}})"},
      {"normal map", R"({"type": "diffuse", "albedo": [0.8, 0.8, 0.8],
                         "normal_map": {"texture": "normals"}})"},
      {"bump map", R"({"type": "diffuse", "albedo": [0.8, 0.8, 0.8],
                       "bump_map": {"texture": "height", "scale": 0.2}})"},
      {"anisotropic", R"({"type": "roughconductor", "alpha_u": 0.05, "alpha_v": 0.4})"},
  };
  constexpr uint32_t kBlock = 4;
  const size_t family = std::size(cases) * (32 / kBlock) * (24 / kBlock) * 3;
  for (const auto& [what, material] : cases) {
    const Scene instanced = instanced_scene(dir, material);
    ASSERT_EQ(instanced.instances.size(), 3u) << what;
    Scene by_hand = instanced;
    ASSERT_EQ(flatten_instances(by_hand, false), 3u);
    const testing::BlockStats a =
        testing::render_blocks(instanced, IntegratorType::kMis, 256, 1, kBlock);
    const testing::BlockStats b =
        testing::render_blocks(by_hand, IntegratorType::kMis, 256, 2, kBlock);
    testing::expect_same_within_noise(a, b, what, family);
  }
}

// A unit quad in the group, mirrored and stretched by its instance: u runs along -x in the world.
// The checkerboard's opacity is 0 where exactly one of u > 1/2 and v > 1/2: those rays pass, for
// hits and shadow rays alike, and the others stop on the instance.
TEST(InstanceSurface, RaysPassThroughAnInstancesCutOutTexelsExactly) {
  testing::TempDir dir;
  const Scene s = scene_from(dir, R"(
    "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "fov_y": 40},
    "film": {"width": 4, "height": 4},
    "textures": {"c": {"type": "checkerboard", "color0": [0, 0, 0], "color1": [1, 1, 1]}},
    "materials": {"m": {"type": "diffuse", "opacity": {"texture": "c", "channel": "r"}}},
    "groups": {"g": [{"type": "quad", "corner": [-1, -1, 0], "edge1": [2, 0, 0],
                      "edge2": [0, 2, 0], "material": "m"}]},
    "shapes": [{"type": "instance", "group": "g",
                "transform": [{"scale": [-2, 1, 1]}, {"translate": [0, 0, 1]}]}])");
  const SceneData data(s);
  ASSERT_EQ(data.instances(), 1u);
  for (const float ox : {-0.5f, 0.5f}) {
    for (const float oy : {-0.5f, 0.5f}) {
      const float u = (ox + 1.f) / 2.f, v = (oy + 1.f) / 2.f;
      const bool open = (u > 0.5f) != (v > 0.5f);
      const Ray ray{{-2.f * ox, oy, 5.f}, {0.f, 0.f, -1.f}};
      const std::optional<RayHit> hit = data.bvh().intersect(ray);
      EXPECT_EQ(hit.has_value(), !open) << "object point " << ox << "," << oy;
      if (hit) {
        EXPECT_EQ(hit->inst, 0u);
        EXPECT_FLOAT_EQ(hit->t, 4.f);
      }
      EXPECT_EQ(data.bvh().occluded(ray), !open) << "object point " << ox << "," << oy;
    }
  }
}

}  // namespace
}  // namespace rayfarm
