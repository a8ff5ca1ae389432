// Textured emitters (renderer/lights/emission_footprint.h): a triangle called black must read
// zero at every point a lookup can reach, whatever the filter, wrap modes, UV transform and
// origin; the triangles that are no lights must not bias the image.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "renderer/lights/emission_footprint.h"
#include "renderer/lights/light_set.h"
#include "tests/renderer/surface_scenes.h"
#include "tests/support/image_writers.h"

namespace rayfarm {
namespace {

/// A 16 x 8 linear RGB image, black but for a few texels: bright ones, and black ones written as
/// negative numbers and NaN (whose positive part is zero too).
DecodedImage spotted_image() {
  DecodedImage image;
  image.width = 16, image.height = 8, image.channels = 3;
  image.floats.assign(16 * 8 * 3, 0.f);
  auto set = [&](uint32_t x, uint32_t y, Vec3 c) {
    for (int k = 0; k < 3; ++k) image.floats[3 * (y * 16 + x) + size_t(k)] = c[k];
  };
  set(5, 3, {4.f, 0.f, 0.f});
  set(12, 1, {0.f, 0.f, 0.5f});
  set(0, 7, {1.f, 1.f, 1.f});  // a corner: reached across the wrap
  set(9, 5, {-1.f, -2.f, 0.f});
  set(2, 2, {NAN, -NAN, 0.f});
  return image;
}

TEST(EmissionFootprint, ATriangleCalledBlackReadsZeroWherePointsOnItLookUp) {
  TextureSet set;
  const uint32_t image = set.load_image("spots.exr", ColourSpace::linear, spotted_image());
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int black = 0, lit = 0;
  const TextureWrap wraps[] = {TextureWrap::repeat, TextureWrap::mirror, TextureWrap::clamp};
  for (const TextureFilter filter : {TextureFilter::bilinear, TextureFilter::nearest})
    for (const TextureWrap wrap_u : wraps)
      for (const TextureWrap wrap_v : wraps)
        for (const UvOrigin origin : {UvOrigin::bottom_left, UvOrigin::top_left})
          for (int transform = 0; transform < 2; ++transform) {
            ImageTextureOptions options;
            options.filter = filter, options.wrap_u = wrap_u, options.wrap_v = wrap_v;
            options.origin = origin;
            if (transform == 1) {
              options.transform.offset = {0.3f, -0.7f};
              options.transform.scale = {2.5f, 0.75f};
              options.transform.rotation = 0.6f;
            }
            Scene scene;
            Material m;
            m.emission = TexturedRgb(Vec3(1.f));
            m.emission.texture = static_cast<int32_t>(set.add_image_texture(image, options));
            scene.materials.push_back(m);
            const EmissionFootprints footprints(scene, set);
            const ImageTexture texture(set.image(image), options);
            for (int trial = 0; trial < 300; ++trial) {
              // Triangles from a thousandth of the image to twice it, anywhere in [-2, 3]^2.
              const double size = std::pow(10.0, -3.0 + 3.3 * unit(rng));
              const Vec2 c(float(-2.0 + 5.0 * unit(rng)), float(-2.0 + 5.0 * unit(rng)));
              Vec2 uv[3];
              for (Vec2& corner : uv)
                corner = c + Vec2(float(size * (unit(rng) - 0.5)), float(size * (unit(rng) - 0.5)));
              const auto found = footprints.find(m.emission.texture, uv);
              ASSERT_TRUE(found.has_value());
              if (!found->black) {
                ++lit;
                EXPECT_GT(found->mean_luminance, 0.0);
                continue;
              }
              ++black;
              // The corners, the edges' midpoints and random points inside, as a hit or a light
              // sample interpolates them (in float).
              for (int k = 0; k < 70; ++k) {
                double b1 = unit(rng), b2 = unit(rng);
                if (k < 3) b1 = k == 1, b2 = k == 2;
                if (k >= 3 && k < 6) b1 = k == 3 ? 0.5 : k == 4 ? 0.0 : 0.5, b2 = k == 5 ? 0.5 : 0.0;
                if (b1 + b2 > 1.0) b1 = 1.0 - b1, b2 = 1.0 - b2;
                const Vec2 p = uv[0] * float(1.0 - b1 - b2) + uv[1] * float(b1) + uv[2] * float(b2);
                const Vec4 t = texture.eval(p.x, p.y);
                EXPECT_FALSE(t.x > 0.f || t.y > 0.f || t.z > 0.f)
                    << "a black triangle reads (" << t.x << ", " << t.y << ", " << t.z << ") at ("
                    << p.x << ", " << p.y << ")";
              }
            }
          }
  // Both answers were exercised, often.
  EXPECT_GT(black, 1000);
  EXPECT_GT(lit, 1000);
}

TEST(EmissionFootprint, TheMeanIsTheTexelsOwnAndACheckerboardHasNoTable) {
  DecodedImage image;
  image.width = 4, image.height = 4, image.channels = 1;
  image.floats.assign(16, 2.f);
  TextureSet set;
  const uint32_t decoded = set.load_image("grey.exr", ColourSpace::linear, image);
  Scene scene;
  Material m;
  m.emission.texture = static_cast<int32_t>(set.add_image_texture(decoded, {}));
  scene.materials.push_back(m);
  Material checker;
  checker.emission.texture = static_cast<int32_t>(set.add_checkerboard(CheckerboardTexture(
      Vec4(1.f, 1.f, 1.f, 1.f), Vec4(0.f, 0.f, 0.f, 1.f))));
  scene.materials.push_back(checker);
  const EmissionFootprints footprints(scene, set);
  const Vec2 uv[3] = {{0.4f, 0.4f}, {0.6f, 0.4f}, {0.5f, 0.6f}};
  const auto grey = footprints.find(m.emission.texture, uv);
  ASSERT_TRUE(grey.has_value());
  EXPECT_FALSE(grey->black);
  EXPECT_NEAR(grey->mean_luminance, 2.0, 1e-9);  // grey: every weight of the luminance sums to 1
  EXPECT_FALSE(footprints.find(checker.emission.texture, uv).has_value());
}

/// An OBJ grid of n x n quads over [-0.8, 0.8]^2 at height z, facing down (-z), with texture
/// coordinates spanning [0, 1]^2.
std::string grid_obj(int n, float z) {
  std::string obj;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const float u = float(i) / float(n), v = float(j) / float(n);
      obj += "v " + std::to_string(-0.8f + 1.6f * u) + " " + std::to_string(-0.8f + 1.6f * v) +
             " " + std::to_string(z) + "\nvt " + std::to_string(u) + " " + std::to_string(v) + "\n";
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i + 1, b = a + 1, c = a + n + 2, d = a + n + 1;
      // Wound clockwise seen from above: the front faces down.
      for (const auto& tri : {std::array{a, d, c}, std::array{a, c, b}}) {
        obj += "f";
        for (int k : tri) obj += " " + std::to_string(k) + "/" + std::to_string(k);
        obj += "\n";
      }
    }
  return obj;
}

// A lamp of 16 x 16 quads whose 32 x 32 emission texture is black but for 17 texels: the
// triangles
// that reach only black texels are no lights, and the floor it lights comes out as naive path
// tracing (which never samples lights) finds it, at 5 standard errors of the difference (two
// comparisons: false alarms below 2 * 6e-7).
TEST(EmissionFootprint, BlackTrianglesAreNoLightsAndTheImageStaysUnbiased) {
  testing::TempDir dir;
  testing::PngSpec png;
  png.width = 32, png.height = 32;
  png.samples.assign(32 * 32 * 3, 0);
  auto red = [&](int x, int y) { png.samples[size_t(3 * (y * 32 + x))] = 255; };
  for (int y = 18; y < 22; ++y)
    for (int x = 8; x < 12; ++x) red(x, y);  // a 4 x 4 block
  red(25, 5);  // and a lone texel
  const testing::Bytes bytes = testing::encode_png(png);
  dir.write("spots.png", std::string(bytes.begin(), bytes.end()));
  dir.write("lamp.obj", grid_obj(16, 1.2f));
  const Scene s = testing::scene_from(dir, R"(
    "camera": {"eye": [0, -3, 1.2], "look_at": [0, 0, 0.3], "fov_y": 45},
    "film": {"width": 12, "height": 12},
    "textures": {"e": {"type": "image", "file": "spots.png"}},
    "materials": {"floor": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]},
                  "lamp": {"type": "diffuse", "albedo": [0, 0, 0],
                           "emission": {"texture": "e", "scale": 40}}},
    "shapes": [{"type": "quad", "corner": [-2, -2, 0], "edge1": [4, 0, 0], "edge2": [0, 4, 0],
                "material": "floor"},
               {"type": "mesh", "file": "lamp.obj", "material": "lamp"}],
    "render": {"max_depth": 2})");
  ASSERT_EQ(s.meshes.size(), 2u);
  ASSERT_EQ(s.meshes[1].triangle_count(), 512u);
  {
    SceneData data(s);
    const LightSet lights(data, LightChoice::kPower);
    // A grid cell covers 2 x 2 texels; with the filter's reach and the margin, a lookup on it
    // reaches 1.5 texels beyond: the block is read from 4 x 4 cells, the lone texel from 3 x 3,
    // 50 triangles. Of 512, at most 64 may be lights.
    EXPECT_GT(lights.area_light_count(), 0u);
    EXPECT_LE(lights.area_light_count(), 64u);
  }
  const auto naive = testing::render_pixels(s, 16384, IntegratorType::kNaive, 5);
  for (const IntegratorType integrator : {IntegratorType::kNee, IntegratorType::kMis}) {
    const auto r = testing::render_pixels(s, 2048, integrator, 7);
    const double se = std::hypot(naive.standard_error(), r.standard_error());
    EXPECT_NEAR(r.image_mean(), naive.image_mean(), 5.0 * se)
        << integrator_name(integrator) << ": standard error " << se;
    EXPECT_LT(se, 0.02 * naive.image_mean()) << "too few samples for a meaningful test";
  }
}

}  // namespace
}  // namespace rayfarm
