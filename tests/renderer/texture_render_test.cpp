// Textured materials rendered: a Lambertian quad under a uniform sky of radiance 1 reflects
// exactly its albedo (one bounce, the ray escapes, Russian roulette survives with probability
// max(albedo) = 1), so every pixel's value is its texel's, with no noise: this checks the texture
// lookup, the quad's texture coordinates and the image's orientation on the film end to end.
#include <gtest/gtest.h>

#include <string>

#include "common/image/fixed.h"
#include "common/image/png.h"
#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"
#include "renderer/renderer.h"

namespace rayfarm {
namespace {

Scene textured_quad(testing::TempDir& dir, const std::string& texture, const std::string& albedo) {
  // Texel 0 (left) red, texel 1 (right) blue.
  write_png_rgb8(dir.path() / "two.png", {255, 0, 0, 0, 0, 255}, 2, 1);
  // The quad spans x, y in [-1, 1] facing +z; from +z, forward x up = +x is the image's right, so
  // u (along edge1 = +x) grows to the right.
  return load_scene(dir.write("scene.json", R"({
    "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "fov_y": 20},
    "film": {"width": 8, "height": 8},
    "textures": {"t": )" + texture + R"(},
    "materials": {"m": {"type": "diffuse", "albedo": )" +
                                                albedo + R"(}},
    "shapes": [{"type": "quad", "corner": [-1, -1, 0], "edge1": [2, 0, 0], "edge2": [0, 2, 0],
                "material": "m"}],
    "background": [1, 1, 1],
    "render": {"integrator": "naive", "max_depth": 1, "spp": 4}})"));
}

/// The mean of each pixel, RGB, row-major.
std::vector<Vec3> pixel_means(const Scene& scene) {
  Renderer renderer(scene, scene.render);
  const TileResult r =
      renderer.render({0, 0, scene.film.width, scene.film.height}, {0, scene.render.spp});
  std::vector<Vec3> out;
  for (size_t p = 0; p < r.rect.pixel_count(); ++p) {
    out.push_back(Vec3(float(from_fixed(r.sum[3 * p])), float(from_fixed(r.sum[3 * p + 1])),
                       float(from_fixed(r.sum[3 * p + 2]))) /
                  float(scene.render.spp));
  }
  return out;
}

void expect_rgb(const Vec3& got, const Vec3& want, const std::string& where) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], 1e-6) << where << " channel " << c;
}

TEST(TextureRenderTest, EachPixelShowsItsTexel) {
  testing::TempDir dir;
  const Scene scene = textured_quad(
      dir, R"({"type": "image", "file": "two.png", "filter": "nearest"})", R"({"texture": "t"})");
  ASSERT_TRUE(scene.materials[0].textured);
  const std::vector<Vec3> px = pixel_means(scene);
  for (uint32_t y = 0; y < 8; ++y)
    for (uint32_t x = 0; x < 8; ++x)
      expect_rgb(px[y * 8 + x], x < 4 ? Vec3(1, 0, 0) : Vec3(0, 0, 1),
                 "pixel " + std::to_string(x) + "," + std::to_string(y));
}

TEST(TextureRenderTest, ScaleMultipliesAndTheUvTransformMoves) {
  testing::TempDir dir;
  // Offset by half a period: the blue texel now covers the left half. The factor halves the
  // value; Russian roulette then survives half the time with double weight, so compare means
  // with their noise allowed for: 4096 samples per pixel, survival 1/2, so the standard error of
  // a pixel's mean is 0.5 / 64; 6 of them over 64 pixels keeps false alarms below 1e-6.
  Scene scene = textured_quad(dir, R"({"type": "image", "file": "two.png", "filter": "nearest",
               "uv_transform": {"offset": [0.5, 0]}})",
                              R"({"texture": "t", "scale": 0.5})");
  scene.render.spp = 4096;
  const std::vector<Vec3> px = pixel_means(scene);
  for (uint32_t y = 0; y < 8; ++y)
    for (uint32_t x = 0; x < 8; ++x) {
      const Vec3 want = x < 4 ? Vec3(0, 0, 0.5f) : Vec3(0.5f, 0, 0);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(px[y * 8 + x][c], want[c], 6 * 0.5 / 64);
    }
}

TEST(TextureRenderTest, AConstantAlbedoIsNotTexturedAndThePlanCountsTheTextures) {
  testing::TempDir dir;
  Scene scene = textured_quad(dir, R"({"type": "image", "file": "two.png"})", "[0.5, 0.5, 0.5]");
  EXPECT_FALSE(scene.materials[0].textured);
  Renderer renderer(scene, scene.render);
  EXPECT_NE(renderer.plan().find("1 textures over 1 images"), std::string::npos) << renderer.plan();
}

}  // namespace
}  // namespace rayfarm
