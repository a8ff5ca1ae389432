// Opacity cut-outs and textured emission, against answers known exactly: seen by an orthographic
// camera whose pixels are aligned with a checkerboard's squares, every pixel lies wholly in one
// square, so each pixel's value is known without noise (camera rays, shadow rays, spheres); a
// textured emitter lit scene must agree between naive, NEE and MIS within their statistics.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "tests/renderer/surface_scenes.h"
#include "renderer/lights/light_set.h"

namespace rayfarm {
namespace {

using testing::kTopView;
using testing::quad_at;
using testing::render_pixels;
using testing::scene_from;

/// World coordinates of pixel (x, y)'s centre under kTopView.
float world_x(uint32_t x) { return -1.f + (float(x) + 0.5f) * 0.25f; }
float world_y(uint32_t y) { return 1.f - (float(y) + 0.5f) * 0.25f; }

/// Whether the checkerboard over the unit quad ([-1, 1]^2, one period) shows colour0 at (x, y):
/// exactly one of u > 1/2 and v > 1/2, that is of x > 0 and y > 0.
bool colour0_at(float x, float y) { return (x > 0.f) != (y > 0.f); }

/// Outside the quad, or in a square whose opacity is 0.
bool open_at(float x, float y) {
  return std::fabs(x) > 1.f || std::fabs(y) > 1.f || colour0_at(x, y);
}

constexpr const char* kAlphaChecker =
    R"("c": {"type": "checkerboard", "color0": [0, 0, 0], "color1": [1, 1, 1]})";

TEST(CutOutTest, CameraRaysPassExactlyWhereTheOpacityIsBelowTheCutoff) {
  testing::TempDir dir;
  const Scene s = scene_from(dir, std::string(kTopView) + R"(,
    "textures": {)" + kAlphaChecker + R"(},
    "materials": {"m": {"type": "diffuse", "albedo": [0, 0, 0],
                        "opacity": {"texture": "c", "channel": "r"}}},
    "shapes": [)" + quad_at(0.f, "m") +
                                      R"(],
    "background": [1, 1, 1])");
  ASSERT_TRUE(s.materials[0].has_alpha());
  const auto r = render_pixels(s, 16, IntegratorType::kNaive);
  // Half the squares are open: the image's mean is exactly 1/2, and each pixel is 0 or 1.
  EXPECT_EQ(r.image_mean(), 0.5);
  for (uint32_t y = 0; y < 8; ++y)
    for (uint32_t x = 0; x < 8; ++x)
      EXPECT_EQ(r.mean[y * 8 + x].x, colour0_at(world_x(x), world_y(y)) ? 1.f : 0.f)
          << "pixel " << x << "," << y;
}

TEST(CutOutTest, ShadowRaysPassThroughTheSameHoles) {
  testing::TempDir dir;
  // A receiver 1 below the cut-out quad, lit by parallel light travelling along (1, 0, -1): a
  // point seen through a hole at (x, y) is lit when the light's way, through (x - 1, y), is open.
  // Radiance there: albedo / pi * irradiance * cos 45 = 0.5.
  const Scene s = scene_from(dir, std::string(kTopView) + R"(,
    "textures": {)" + kAlphaChecker + R"(},
    "materials": {"m": {"type": "diffuse", "albedo": [0, 0, 0],
                        "opacity": {"texture": "c", "channel": "r"}},
                  "floor": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
    "shapes": [)" + quad_at(0.f, "m") +
                                      ", " + quad_at(-1.f, "floor") + R"(],
    "lights": [{"type": "directional", "direction": [1, 0, -1],
                "irradiance": [4.442882938158366, 4.442882938158366, 4.442882938158366]}],
    "render": {"max_depth": 1})");
  for (const IntegratorType integrator : {IntegratorType::kNee, IntegratorType::kMis}) {
    const auto r = render_pixels(s, 8, integrator);
    int lit = 0;
    for (uint32_t y = 0; y < 8; ++y)
      for (uint32_t x = 0; x < 8; ++x) {
        const float wx = world_x(x), wy = world_y(y);
        const bool want = open_at(wx, wy) && open_at(wx - 1.f, wy);
        lit += want;
        EXPECT_NEAR(r.mean[y * 8 + x].x, want ? 0.5f : 0.f, 1e-5f) << "pixel " << x << "," << y;
      }
    EXPECT_EQ(lit, 16) << "the holes of the left column and the ones the light sees past";
  }
}

TEST(CutOutTest, SpheresAreCutWhereTheirTextureCoordinatesSaySo) {
  testing::TempDir dir;
  // u = phi / 2pi around +z: scaling v away leaves colour0, opacity 0, where phi > pi (y < 0).
  // Rays there pass both the front and the back of the sphere.
  const Scene s = scene_from(dir, std::string(kTopView) + R"(,
    "textures": {"c": {"type": "checkerboard", "color0": [0, 0, 0], "color1": [1, 1, 1],
                       "uv_transform": {"scale": [1, 0]}}},
    "materials": {"m": {"type": "diffuse", "albedo": [0, 0, 0],
                        "opacity": {"texture": "c", "channel": "r"}}},
    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.95, "material": "m"}],
    "background": [1, 1, 1])");
  const auto r = render_pixels(s, 16, IntegratorType::kNaive);
  int checked = 0;
  for (uint32_t y = 0; y < 8; ++y)
    for (uint32_t x = 0; x < 8; ++x) {
      // Only pixels wholly inside or wholly outside the disk have one answer.
      const float cx = world_x(x), cy = world_y(y);
      const float near_r =
          std::hypot(std::max(0.f, std::fabs(cx) - 0.125f), std::max(0.f, std::fabs(cy) - 0.125f));
      const float far_r = std::hypot(std::fabs(cx) + 0.125f, std::fabs(cy) + 0.125f);
      float want;
      if (far_r < 0.95f) {
        want = cy < 0.f ? 1.f : 0.f;
      } else if (near_r > 0.95f) {
        want = 1.f;
      } else {
        continue;
      }
      ++checked;
      EXPECT_EQ(r.mean[y * 8 + x].x, want) << "pixel " << x << "," << y;
    }
  EXPECT_GT(checked, 20);
}

TEST(CutOutTest, AConstantOpacityBelowTheCutoffHidesEverything) {
  testing::TempDir dir;
  const Scene s = scene_from(dir, std::string(kTopView) + R"(,
    "materials": {"m": {"type": "diffuse", "albedo": [0, 0, 0], "opacity": 0.3},
                  "n": {"type": "diffuse", "albedo": [0, 0, 0], "opacity": 0.3,
                        "alpha_cutoff": 0.2}},
    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "material": "m"},
               {"type": "quad", "corner": [0, 0, 1], "edge1": [1, 0, 0], "edge2": [0, 1, 0],
                "material": "n"}],
    "background": [1, 1, 1])");
  EXPECT_FALSE(s.materials[1].has_alpha()) << "0.3 is above that cutoff: opaque, no filter";
  const auto r = render_pixels(s, 4, IntegratorType::kNaive);
  for (uint32_t y = 0; y < 8; ++y)
    for (uint32_t x = 0; x < 8; ++x) {
      const bool under_quad = world_x(x) > 0.f && world_y(y) > 0.f;
      EXPECT_EQ(r.mean[y * 8 + x].x, under_quad ? 0.f : 1.f) << "pixel " << x << "," << y;
    }
}

// Partial coverage ("coverage": "blend"): a black quad of opacity 0.3 over a floor lit through it.
// A camera ray stops at the quad with probability 0.3 (black) and reaches the floor otherwise; the
// floor's shadow ray passes with probability 0.7 too, independently (another ray): a floor pixel's
// samples are 0.5 with probability 0.49, else 0. Over 64 pixels x 1024 samples the mean's standard
// error is 0.5 sqrt(0.49 * 0.51 / 65536) = 9.8e-4; the test allows 4.5 of them (two tests).
TEST(CutOutTest, PartialCoverageStopsRaysWithTheOpacitysProbability) {
  testing::TempDir dir;
  const Scene s = scene_from(dir, std::string(kTopView) + R"(,
    "materials": {"m": {"type": "diffuse", "albedo": [0, 0, 0], "opacity": 0.3,
                        "coverage": "blend"},
                  "floor": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
    "shapes": [{"type": "quad", "corner": [-4, -4, 0], "edge1": [8, 0, 0], "edge2": [0, 8, 0],
                "material": "m"},
               {"type": "quad", "corner": [-4, -4, -1], "edge1": [8, 0, 0], "edge2": [0, 8, 0],
                "material": "floor"}],
    "lights": [{"type": "directional", "direction": [1, 0, -1],
                "irradiance": [4.442882938158366, 4.442882938158366, 4.442882938158366]}],
    "render": {"max_depth": 1})");
  ASSERT_TRUE(s.materials[0].has_alpha());
  for (const IntegratorType integrator : {IntegratorType::kNee, IntegratorType::kMis}) {
    const auto r = render_pixels(s, 1024, integrator);
    EXPECT_NEAR(r.image_mean(), 0.245, 4.5 * 9.8e-4) << integrator_name(integrator);
    // The same ray decides the same way: the same seed gives the same bits, another seed not.
    const auto again = render_pixels(s, 1024, integrator);
    EXPECT_EQ(again.total, r.total);
    EXPECT_NE(render_pixels(s, 1024, integrator, 2).total, r.total);
  }
}

TEST(TexturedEmissionTest, AnEmitterSeenDirectlyShowsItsTexture) {
  testing::TempDir dir;
  const Scene s = scene_from(dir, std::string(kTopView) + R"(,
    "textures": {"e": {"type": "checkerboard", "color0": [1, 0, 0.5], "color1": [0, 0.25, 1]}},
    "materials": {"m": {"type": "diffuse", "albedo": [0, 0, 0],
                        "emission": {"texture": "e", "scale": [2, 4, 8]}}},
    "shapes": [)" + quad_at(0.f, "m") +
                                      R"(],
    "render": {"max_depth": 0})");
  for (const IntegratorType integrator :
       {IntegratorType::kNaive, IntegratorType::kNee, IntegratorType::kMis}) {
    const auto r = render_pixels(s, 4, integrator);
    for (uint32_t y = 0; y < 8; ++y)
      for (uint32_t x = 0; x < 8; ++x) {
        const Vec3 want =
            colour0_at(world_x(x), world_y(y)) ? Vec3(2.f, 0.f, 4.f) : Vec3(0.f, 1.f, 8.f);
        EXPECT_EQ(r.mean[y * 8 + x], want) << "pixel " << x << "," << y;
      }
  }
}

TEST(TexturedEmissionTest, LightSamplingAgreesWithBsdfSampling) {
  testing::TempDir dir;
  // A floor lit by a textured quad facing it and a textured sphere; red varies across both
  // textures, so reading the wrong texel would move the mean. Two comparisons against naive at
  // 5 standard errors of the difference: false alarms below 2 * 6e-7.
  const Scene s = scene_from(dir, R"(
    "camera": {"eye": [0, -3, 1.2], "look_at": [0, 0, 0.3], "fov_y": 45},
    "film": {"width": 12, "height": 12},
    "textures": {"e": {"type": "checkerboard", "color0": [3, 0.5, 0.5], "color1": [0.2, 0.5, 3]},
                 "s": {"type": "checkerboard", "color0": [0.1, 1, 1], "color1": [4, 1, 1],
                       "uv_transform": {"scale": [2, 1]}}},
    "materials": {"floor": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]},
                  "lamp": {"type": "diffuse", "albedo": [0, 0, 0],
                           "emission": {"texture": "e"}},
                  "ball": {"type": "diffuse", "albedo": [0, 0, 0],
                           "emission": {"texture": "s"}}},
    "shapes": [{"type": "quad", "corner": [-2, -2, 0], "edge1": [4, 0, 0], "edge2": [0, 4, 0],
                "material": "floor"},
               {"type": "quad", "corner": [-0.8, -0.8, 1.2], "edge1": [0, 1.6, 0],
                "edge2": [1.6, 0, 0], "material": "lamp"},
               {"type": "sphere", "center": [0.9, 0.4, 0.4], "radius": 0.3, "material": "ball"}],
    "render": {"max_depth": 2})");
  const auto naive = render_pixels(s, 4096, IntegratorType::kNaive, 5);
  for (const IntegratorType integrator : {IntegratorType::kNee, IntegratorType::kMis}) {
    const auto r = render_pixels(s, 1024, integrator, 7);
    const double se = std::hypot(naive.standard_error(), r.standard_error());
    EXPECT_NEAR(r.image_mean(), naive.image_mean(), 5.0 * se)
        << integrator_name(integrator) << ": standard error " << se;
    EXPECT_LT(se, 0.02 * naive.image_mean()) << "too few samples for a meaningful test";
  }
}

TEST(TexturedEmissionTest, LightSelectionWeighsTheTexturesMean) {
  testing::TempDir dir;
  // Equal quads: constant 1; a checkerboard of 0 and 2 (mean 1); the same times 3 (mean 3).
  const Scene s = scene_from(dir, R"(
    "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "fov_y": 20},
    "film": {"width": 4, "height": 4},
    "textures": {"e": {"type": "checkerboard", "color0": [0, 0, 0], "color1": [2, 2, 2]}},
    "materials": {"a": {"type": "diffuse", "emission": [1, 1, 1]},
                  "b": {"type": "diffuse", "emission": {"texture": "e"}},
                  "c": {"type": "diffuse", "emission": {"texture": "e", "scale": 3}}},
    "shapes": [{"type": "quad", "corner": [0, 0, 0], "edge1": [1, 0, 0], "edge2": [0, 1, 0],
                "material": "a"},
               {"type": "quad", "corner": [2, 0, 0], "edge1": [1, 0, 0], "edge2": [0, 1, 0],
                "material": "b"},
               {"type": "quad", "corner": [4, 0, 0], "edge1": [1, 0, 0], "edge2": [0, 1, 0],
                "material": "c"}])");
  SceneData data(s);
  const LightSet lights(data, LightChoice::kPower);
  ASSERT_EQ(lights.area_light_count(), 6u);
  // Two triangles per quad, in shape order: 1 : 1 : 3.
  for (int32_t i = 0; i < 6; ++i)
    EXPECT_NEAR(lights.selection_probability(i, Vec3(0.f), Vec3(0.f)), (i < 4 ? 1.0 : 3.0) / 10.0,
                1e-6)
        << i;
}

}  // namespace
}  // namespace rayfarm
