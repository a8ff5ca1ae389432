// Lights at infinity and cones (renderer/lights/environment_light.h, spot_light.h,
// directional_light.h): the environment map's orientation, its sampling density (integrates to
// one, matches the histogram of its samples, agrees with eval at every sample), its irradiance
// against a sum over texels, its rotation; and the three integrators under a constant and an
// image environment, a spot light and a directional light, against closed forms.
//
// Statistics. Every Monte Carlo assertion is a test at significance kAlpha / kHypotheses
// (Bonferroni over the file's kHypotheses, family-wise kAlpha = 0.01): a z test of a sample mean
// with the standard error from the sample variance, or a chi-square test of a histogram whose
// statistic X over k degrees of freedom is compared through the Wilson-Hilferty approximation
// ((X/k)^(1/3) is near normal with mean 1 - 2/(9k) and variance 2/(9k); k is in the hundreds
// here, where it is accurate to far better than the threshold needs). Streams are seeded.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <memory>
#include <vector>

#include "common/scene/scene.h"
#include "renderer/lights/light_set.h"
#include "renderer/samplers/rng.h"
#include "renderer/scene_data.h"
#include "tests/renderer/mc_stats.h"
#include "tests/support/normal_quantile.h"

namespace rayfarm {
namespace {

constexpr double kPiD = 3.141592653589793;
// z tests: 1 (pdf integral) + 3 (irradiance channels) + 6 (renders: 3 integrators x 2 maps);
// chi-square: 1.
constexpr int kHypotheses = 1 + 3 + 6 + 1;
constexpr double kAlpha = 0.01;
const double kZ = testing::two_sided_z(kAlpha / kHypotheses);

constexpr uint32_t kW = 16, kH = 8;

/// A 16x8 map: a dim coloured ramp, and a bright block high in the sky around u = 0.3.
std::shared_ptr<const DecodedImage> test_image() {
  auto img = std::make_shared<DecodedImage>();
  img->width = kW, img->height = kH, img->channels = 3, img->format = "test";
  for (uint32_t y = 0; y < kH; ++y) {
    for (uint32_t x = 0; x < kW; ++x) {
      const bool sun = y >= 1 && y <= 2 && x >= 4 && x <= 5;
      img->floats.push_back(sun ? 20.f : 0.1f + 0.05f * x);
      img->floats.push_back(sun ? 15.f : 0.2f);
      img->floats.push_back(sun ? 10.f : 0.3f + 0.02f * y);
    }
  }
  return img;
}

Vec3 texel(const DecodedImage& img, uint32_t x, uint32_t y) {
  const float* t = &img.floats[3 * (size_t(y) * img.width + x)];
  return {t[0], t[1], t[2]};
}

/// A scene with one diffuse quad in y = 0 facing +y, seen from above by every pixel.
Scene quad_scene(float albedo) {
  Scene s;
  s.film = {4, 4};
  s.camera.eye = {0.f, 3.f, 0.f};
  s.camera.look_at = {0.f, 0.f, 0.f};
  s.camera.up = {0.f, 0.f, 1.f};
  s.camera.fov_y_deg = 20.f;
  Material m;
  m.kind = DiffuseMaterial{Vec3(albedo)};
  s.materials.push_back(m);
  TriangleMesh mesh;
  // Corner (-1, 0, -1), edges (0, 0, 2) and (2, 0, 0): front face +y.
  mesh.positions = {{-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1}};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  mesh.materials = {0, 0};
  s.meshes.push_back(mesh);
  s.render.max_depth = 1;
  return s;
}

EnvironmentMap image_map(const std::array<double, 9>& rotation = {1, 0, 0, 0, 1, 0, 0, 0, 1}) {
  EnvironmentMap env;
  env.file = "sky.hdr";
  env.image = test_image();
  env.rotation = rotation;
  return env;
}

/// Irradiance on a surface of normal n under the test map: each texel's radiance times the
/// integral of the cosine over its solid angle, by a fine midpoint rule, in the documented
/// orientation (u = 0 looks along -z, u = 1/4 along +x, v = 0 up along +y).
std::array<double, 3> irradiance_by_texels(const Vec3& n) {
  const auto img = test_image();
  std::array<double, 3> e{0, 0, 0};
  constexpr int kSub = 24;
  for (uint32_t y = 0; y < kH; ++y) {
    for (uint32_t x = 0; x < kW; ++x) {
      double weight = 0.0;
      for (int j = 0; j < kSub; ++j) {
        const double theta = kPiD * (y + (j + 0.5) / kSub) / kH;
        for (int i = 0; i < kSub; ++i) {
          const double phi = 2.0 * kPiD * (x + (i + 0.5) / kSub) / kW;
          const double d[3] = {std::sin(theta) * std::sin(phi), std::cos(theta),
                               -std::sin(theta) * std::cos(phi)};
          const double c = d[0] * n.x + d[1] * n.y + d[2] * n.z;
          weight += std::max(c, 0.0) * std::sin(theta);
        }
      }
      weight *= (kPiD / kH / kSub) * (2.0 * kPiD / kW / kSub);
      const Vec3 l = texel(*img, x, y);
      for (int c = 0; c < 3; ++c) e[c] += l[c] * weight;
    }
  }
  return e;
}

struct Lights {
  explicit Lights(Scene s) : scene(std::move(s)), data(scene), set(data) {}
  Scene scene;
  SceneData data;
  LightSet set;
};

Scene environment_scene(EnvironmentMap env) {
  Scene s = quad_scene(0.5f);
  s.environment = std::move(env);
  return s;
}

TEST(EnvironmentLightTest, OrientationFollowsTheDocumentedConvention) {
  const Lights l(environment_scene(image_map()));
  const EnvironmentLight* env = l.set.environment();
  ASSERT_NE(env, nullptr);
  const auto near = [](const Vec3& a, const Vec3& b) { return length(a - b) < 1e-5f; };
  EXPECT_TRUE(near(env->direction(0.5f, 0.5f), {0, 0, 1})) << "the image's centre looks along +z";
  EXPECT_TRUE(near(env->direction(0.25f, 0.5f), {1, 0, 0}));
  EXPECT_TRUE(near(env->direction(0.75f, 0.5f), {-1, 0, 0}));
  EXPECT_TRUE(near(env->direction(0.f, 0.5f), {0, 0, -1}));
  EXPECT_TRUE(near(env->direction(0.3f, 0.f), {0, 1, 0})) << "the top row looks up";
  // The bright block (columns 4-5, rows 1-2) lies towards +x, high up.
  const Vec3 sun = env->direction(5.f / kW, 2.f / kH);
  EXPECT_EQ(env->eval(sun), Vec3(20.f, 15.f, 10.f));
  EXPECT_GT(sun.x, 0.5f);
  EXPECT_GT(sun.y, 0.5f);
}

TEST(EnvironmentLightTest, DensityIntegratesToOneAndMatchesItsSamples) {
  const Lights l(environment_scene(image_map()));
  const EnvironmentLight& env = *l.set.environment();
  // The integral over the sphere: uniform directions, mean of pdf x 4 pi.
  Pcg32 rng(7, 1);
  constexpr int kN = 400000;
  double sum = 0.0, sum_sq = 0.0;
  for (int i = 0; i < kN; ++i) {
    const double z = 1.0 - 2.0 * rng.next_float(), phi = 2.0 * kPiD * rng.next_float();
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Vec3 d(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z));
    const double f = env.pdf_direction(d) * 4.0 * kPiD;
    sum += f, sum_sq += f * f;
  }
  const double mean = sum / kN, se = std::sqrt((sum_sq / kN - mean * mean) / (kN - 1));
  EXPECT_LT(std::fabs(mean - 1.0), kZ * se) << mean << " +- " << se;

  // Histogram over a grid of half texels (16 x 32 in v and u, the map's own coordinates computed
  // here from the documented orientation), so that the density is smooth within each bin and a
  // midpoint rule over the bin's solid angle gives its expected count; it checks the rows'
  // and columns' shares and the spread within each texel.
  constexpr int kRows = 2 * kH, kCols = 2 * kW, kSub = 8, kSamples = 400000;
  std::vector<double> observed(kRows * kCols, 0.0), expected(kRows * kCols, 0.0);
  const auto bin = [&](const Vec3& d) {
    const double theta = std::atan2(std::hypot(double(d.x), double(d.z)), double(d.y));
    double u = std::atan2(double(d.x), -double(d.z)) / (2.0 * kPiD);
    if (u < 0) u += 1.0;
    const int row = std::min(kRows - 1, int(theta / kPiD * kRows));
    const int col = std::min(kCols - 1, int(u * kCols));
    return row * kCols + col;
  };
  for (int r = 0; r < kRows; ++r) {
    for (int c = 0; c < kCols; ++c) {
      double p = 0.0;
      for (int j = 0; j < kSub; ++j) {
        const double theta = kPiD * (r + (j + 0.5) / kSub) / kRows;
        for (int i = 0; i < kSub; ++i) {
          const double phi = 2.0 * kPiD * (c + (i + 0.5) / kSub) / kCols;
          const Vec3 d(float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)),
                       float(-std::sin(theta) * std::cos(phi)));
          p += env.pdf_direction(d) * std::sin(theta);
        }
      }
      expected[r * kCols + c] = p * (kPiD / kRows / kSub) * (2.0 * kPiD / kCols / kSub) * kSamples;
    }
  }
  int mismatches = 0;
  for (int i = 0; i < kSamples; ++i) {
    LightSample ls;
    ASSERT_TRUE(env.sample(Vec3(0.f), 1.f, rng.next_float(), rng.next_float(), ls));
    EXPECT_TRUE(ls.infinite);
    EXPECT_FALSE(ls.delta);
    observed[bin(ls.wi)] += 1.0;
    // eval and pdf at the sampled direction are those the sample carries; a direction that
    // rounds into the neighbouring texel may differ, and there are few of them.
    const float pdf = env.pdf_direction(ls.wi);
    if (!(env.eval(ls.wi) == ls.radiance && std::fabs(pdf - ls.pdf) <= 1e-3f * ls.pdf))
      ++mismatches;
  }
  EXPECT_LE(mismatches, kSamples / 10000) << "eval or pdf disagree with the sample";
  double x2 = 0.0;
  int dof = -1;
  for (size_t i = 0; i < observed.size(); ++i) {
    ASSERT_GT(expected[i], 20.0) << "bin " << i << " too small for the chi-square approximation";
    x2 += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
    ++dof;
  }
  const double k = dof, m = 1.0 - 2.0 / (9.0 * k), s = std::sqrt(2.0 / (9.0 * k));
  const double z = (std::cbrt(x2 / k) - m) / s;
  // One-sided: only a large statistic is evidence of a mismatch.
  EXPECT_LT(z, testing::two_sided_z(2.0 * kAlpha / kHypotheses))
      << "chi-square " << x2 << ", dof " << dof;
}

TEST(EnvironmentLightTest, SampledIrradianceEqualsTheSumOverTexels) {
  const Lights l(environment_scene(image_map()));
  const Vec3 n = normalize(Vec3(1.f, 1.f, 0.5f));
  const std::array<double, 3> expected = irradiance_by_texels(n);
  Pcg32 rng(11, 3);
  constexpr int kN = 400000;
  std::array<double, 3> sum{}, sum_sq{};
  for (int i = 0; i < kN; ++i) {
    LightSample ls;
    const float us = rng.next_float(), u1 = rng.next_float(), u2 = rng.next_float();
    if (!l.set.sample(Vec3(0.f, 5.f, 0.f), Vec3(0.f), SelectionNumber::from_float(us), u1, u2, ls))
      continue;
    const float c = std::max(dot(ls.wi, n), 0.f);
    for (int ch = 0; ch < 3; ++ch) {
      const double f = ls.radiance[ch] * c / ls.pdf;
      sum[ch] += f, sum_sq[ch] += f * f;
    }
  }
  for (int ch = 0; ch < 3; ++ch) {
    const double mean = sum[ch] / kN;
    const double se = std::sqrt((sum_sq[ch] / kN - mean * mean) / (kN - 1));
    EXPECT_LT(std::fabs(mean - expected[ch]), kZ * se)
        << "channel " << ch << ": " << mean << " +- " << se << ", expected " << expected[ch];
  }
}

TEST(EnvironmentLightTest, RotatedMapIsTheMapLookedUpWithTheInverseRotation) {
  // 90 degrees about +y, then 30 about +x: R = Rx(30) Ry(90), row-major, world from map.
  const double c = std::cos(kPiD / 6), s = std::sin(kPiD / 6);
  const std::array<double, 9> ry = {0, 0, 1, 0, 1, 0, -1, 0, 0};
  const std::array<double, 9> rx = {1, 0, 0, 0, c, -s, 0, s, c};
  std::array<double, 9> r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) r[3 * i + j] += rx[3 * i + k] * ry[3 * k + j];
  const Lights plain(environment_scene(image_map()));
  const Lights rotated(environment_scene(image_map(r)));
  Pcg32 rng(5, 9);
  int differ = 0;
  constexpr int kN = 20000;
  for (int i = 0; i < kN; ++i) {
    const double z = 1.0 - 2.0 * rng.next_float(), phi = 2.0 * kPiD * rng.next_float();
    const double q = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double d[3] = {q * std::cos(phi), q * std::sin(phi), z};
    // R^T d: the direction in the map's frame.
    const Vec3 local(float(r[0] * d[0] + r[3] * d[1] + r[6] * d[2]),
                     float(r[1] * d[0] + r[4] * d[1] + r[7] * d[2]),
                     float(r[2] * d[0] + r[5] * d[1] + r[8] * d[2]));
    const Vec3 world{float(d[0]), float(d[1]), float(d[2])};
    // Directions within rounding of a texel edge may fall either side.
    if (!(rotated.set.environment()->eval(world) == plain.set.environment()->eval(local))) ++differ;
  }
  EXPECT_LE(differ, kN / 1000);
  // The image's centre now looks along R (0, 0, 1).
  const Vec3 centre = rotated.set.environment()->direction(0.5f, 0.5f);
  EXPECT_NEAR(centre.x, r[2], 1e-5);
  EXPECT_NEAR(centre.y, r[5], 1e-5);
  EXPECT_NEAR(centre.z, r[8], 1e-5);
}

/// Every integrator renders the quad under `env` to albedo / pi x irradiance.
void expect_quad_radiance(const EnvironmentMap& env, double expected) {
  Scene s = environment_scene(env);
  for (const IntegratorType type :
       {IntegratorType::kNaive, IntegratorType::kNee, IntegratorType::kMis}) {
    RenderSettings settings = s.render;
    settings.integrator = type;
    settings.spp = 4096;
    const testing::Estimate e = testing::image_estimate(s, settings);
    EXPECT_EQ(e.nonfinite, 0u);
    // Float rounding of the per-sample weights adds 1e-6 relative (a constant sky under NEE and
    // naive sampling before roulette has no variance at all).
    EXPECT_LE(std::fabs(e.mean - expected), kZ * e.standard_error + 1e-6 * expected)
        << integrator_name(type) << ": " << e.mean << " +- " << e.standard_error << ", expected "
        << expected;
  }
}

// A map read bilinearly (Mitsuba's envmap): texel centres at u = (i + 1/2) / width, rows from
// pole to pole; every sample carries the radiance eval() gives its direction, and every
// direction with light can be drawn (its density is positive).
TEST(EnvironmentLightTest, BilinearMapsInterpolateBetweenTexelCentresAndSampleWhatTheyShow) {
  EnvironmentMap map = image_map();
  map.bilinear = true;
  const Lights l(environment_scene(map));
  const EnvironmentLight& env = *l.set.environment();
  const DecodedImage& img = *map.image;
  // At a texel's centre column and an exact row, the texel itself.
  const Vec3 centre = env.eval(env.direction(5.5f / kW, 2.f / (kH - 1)));
  EXPECT_LT(length(centre - texel(img, 5, 2)), 1e-4f * length(texel(img, 5, 2)));
  // Halfway between two columns, their mean; columns wrap around at u = 0.
  const Vec3 mid = env.eval(env.direction(1.f / kW, 3.f / (kH - 1)));
  const Vec3 want = (texel(img, 0, 3) + texel(img, 1, 3)) * 0.5f;
  EXPECT_LT(length(mid - want), 1e-4f * length(want));
  const Vec3 seam = env.eval(env.direction(0.f, 3.f / (kH - 1)));
  const Vec3 want_seam = (texel(img, kW - 1, 3) + texel(img, 0, 3)) * 0.5f;
  EXPECT_LT(length(seam - want_seam), 1e-4f * length(want_seam));
  Pcg32 rng(11, 3);
  for (int i = 0; i < 20000; ++i) {
    LightSample ls;
    if (!env.sample(Vec3(0.f), 1.f, rng.next_float(), rng.next_float(), ls)) continue;
    ASSERT_EQ(ls.radiance, env.eval(ls.wi)) << i;
    const float u1 = rng.next_float(), u2 = rng.next_float();
    const Vec3 d = env.direction(u1, u2);
    if (!is_black(env.eval(d)) && std::sin(u2 * kPiD) > 1e-3) {
      ASSERT_GT(env.pdf_direction(d), 0.f) << i;
    }
  }
}

TEST(EnvironmentRenderTest, DiffuseQuadUnderConstantEnvironmentIsAlbedoTimesRadiance) {
  EnvironmentMap env;
  env.scale = Vec3(0.5f, 2.f, 1.f);
  expect_quad_radiance(env, 0.5 * 2.0);  // green channel: albedo 0.5 x radiance 2
}

TEST(EnvironmentRenderTest, DiffuseQuadUnderImageEnvironmentMatchesTheTexelSum) {
  expect_quad_radiance(image_map(), 0.5 / kPiD * irradiance_by_texels(Vec3(0.f, 1.f, 0.f))[1]);
}

TEST(SpotLightTest, IrradianceInBeamFalloffAndOutside) {
  Scene s = quad_scene(0.5f);
  SpotLight spot;
  spot.position = {0.f, 2.f, 0.f};
  spot.direction = {0.f, -1.f, 0.f};
  spot.intensity = {3.f, 6.f, 9.f};
  spot.cutoff_deg = 40.f;
  spot.beam_width_deg = 20.f;
  s.spot_lights.push_back(spot);
  const Lights l(std::move(s));
  ASSERT_EQ(l.set.spot_light_count(), 1u);
  // Points on the floor at angle a from the axis: irradiance I f(a) cos(a) / d^2 with
  // f = 1 inside 20 degrees, (40 - a) / 20 between, 0 beyond 40.
  for (const double deg : {0.0, 10.0, 25.0, 30.0, 39.0, 41.0, 60.0}) {
    const double a = deg * kPiD / 180.0;
    const Vec3 p(float(2.0 * std::tan(a)), 0.f, 0.f);
    const double d2 = 4.0 + double(p.x) * p.x;
    const double f = deg <= 20.0 ? 1.0 : (deg < 40.0 ? (40.0 - deg) / 20.0 : 0.0);
    LightSample ls;
    const bool ok = l.set.sample(p, Vec3(0.f), SelectionNumber::from_float(0.5f), 0.5f, 0.5f, ls);
    if (f == 0.0) {
      EXPECT_FALSE(ok) << deg << " degrees is outside the cone";
      continue;
    }
    ASSERT_TRUE(ok) << deg;
    EXPECT_TRUE(ls.delta);
    const double e = ls.radiance.y * std::max(0.f, ls.wi.y) / ls.pdf;
    EXPECT_NEAR(e, 6.0 * f * std::cos(a) / d2, 1e-4 * 6.0 / d2) << deg << " degrees";
  }
}

// ---- spot lights that cast an image (image_spot_light.h) ------------------------------------
// A light 2 above the floor looking down (-y), its frame x = +x, y = +z. A 2x2 image, read at
// its texels (nearest, top-left origin): row 0 red, green; row 1 blue, white.

std::shared_ptr<const DecodedImage> four_texels() {
  auto img = std::make_shared<DecodedImage>();
  img->width = img->height = 2;
  img->channels = 3;
  img->floats = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
  return img;
}

Scene image_spot_scene(bool projector, bool textured) {
  Scene s = quad_scene(0.5f);
  if (textured) {
    TextureDesc t;
    t.name = "four";
    t.image = four_texels();
    t.space = ColourSpace::linear;
    t.options.filter = TextureFilter::nearest;
    t.options.origin = UvOrigin::top_left;
    s.textures.push_back(t);
  }
  SpotLight spot;
  spot.position = {0.f, 2.f, 0.f};
  spot.direction = {0.f, -1.f, 0.f};
  spot.intensity = {3.f, 6.f, 9.f};
  SpotImage image;
  image.x_axis = {1.f, 0.f, 0.f};
  image.y_axis = {0.f, 0.f, 1.f};
  if (textured) image.image.texture = 0;
  if (projector) {
    // A 90-degree frustum, as Mitsuba maps it: u = 0.5 - 0.5 x / z, v = 0.5 - 0.5 y / z; the
    // cone through its corners, at full intensity within.
    image.u_scale = image.v_scale = -0.5f;
    image.projector = true;
    spot.cutoff_deg = spot.beam_width_deg = float(std::atan(std::sqrt(2.0)) * 180.0 / kPiD);
  } else {
    spot.cutoff_deg = 40.f;
    spot.beam_width_deg = 20.f;
    image.u_scale = image.v_scale = float(0.5 / std::tan(40.0 * kPiD / 180.0));
  }
  spot.image = image;
  s.spot_lights.push_back(spot);
  return s;
}

/// Irradiance at floor point p (normal +y) from the scene's one light; 0 when it sends nothing.
double floor_irradiance(const LightSet& set, const Vec3& p, int channel) {
  LightSample ls;
  if (!set.sample(p, Vec3(0.f), SelectionNumber::from_float(0.5f), 0.5f, 0.5f, ls)) return 0.0;
  EXPECT_TRUE(ls.delta);
  return ls.radiance[channel] * std::max(0.f, ls.wi.y) / ls.pdf;
}

// A projector of a constant image lights its frustum's rectangle on a plane facing it evenly,
// intensity / h^2 (its 1 / cos^3 cancels the distance and the slant), and nothing beyond.
TEST(ImageSpotLightTest, AProjectorLightsItsRectangleEvenly) {
  const Lights l(image_spot_scene(true, false));
  ASSERT_EQ(l.set.spot_light_count(), 1u);
  for (const float x : {0.f, 0.7f, -1.3f, 1.99f}) {
    for (const float z : {0.f, 1.5f, -1.99f}) {
      EXPECT_NEAR(floor_irradiance(l.set, Vec3(x, 0.f, z), 1), 6.0 / 4.0, 1e-5)
          << "(" << x << ", " << z << ")";
    }
  }
  // The rectangle on the floor is [-2, 2]^2 (tan 45 degrees x 2).
  EXPECT_EQ(floor_irradiance(l.set, Vec3(2.01f, 0.f, 0.f), 1), 0.0);
  EXPECT_EQ(floor_irradiance(l.set, Vec3(0.f, 0.f, -2.01f), 1), 0.0);
  EXPECT_EQ(floor_irradiance(l.set, Vec3(0.f, 3.f, 0.f), 1), 0.0) << "behind it";
}

// The image's texel at the direction's (u, v): a projector's u grows towards its frame's -x and
// v towards -y (Mitsuba's sample space), a textured spot's towards +x and +y.
TEST(ImageSpotLightTest, TheImageIsReadAtTheDirectionsUv) {
  const Vec3 red(1.f, 0.f, 0.f), green(0.f, 1.f, 0.f), blue(0.f, 0.f, 1.f), white(1.f);
  struct Probe {
    float x, z;
    Vec3 projector, spot;  // the texel each sees there
  };
  const Probe probes[] = {{1.f, 1.f, red, white},
                          {-1.f, 1.f, green, blue},
                          {1.f, -1.f, blue, green},
                          {-1.f, -1.f, white, red}};
  for (const bool projector : {true, false}) {
    const Lights l(image_spot_scene(projector, true));
    for (const Probe& p : probes) {
      const Vec3 q(p.x * 0.4f, 0.f, p.z * 0.4f);  // within a spot's beam too (16 degrees)
      const double d2 = 4.0 + double(q.x) * q.x + double(q.z) * q.z;
      const double cos_a = 2.0 / std::sqrt(d2);
      // A projector: intensity / h^2 x texel; a spot: intensity x texel x cos / d^2.
      const double base = projector ? 1.0 / 4.0 : cos_a / d2;
      const Vec3 texel = projector ? p.projector : p.spot;
      for (int c = 0; c < 3; ++c) {
        const double intensity = 3.0 * (c + 1);
        EXPECT_NEAR(floor_irradiance(l.set, q, c), intensity * texel[c] * base, 1e-5)
            << (projector ? "projector" : "spot") << " at (" << q.x << ", " << q.z << "), channel "
            << c;
      }
    }
  }
}

TEST(DirectionalLightTest, IrradianceIsIrradianceTimesCosine) {
  Scene s = quad_scene(0.5f);
  const double a = 35.0 * kPiD / 180.0;
  s.directional_lights.push_back(
      {Vec3(float(std::sin(a)), float(-std::cos(a)), 0.f), Vec3(2.f, 4.f, 1.f)});
  for (const IntegratorType type : {IntegratorType::kNee, IntegratorType::kMis}) {
    RenderSettings settings = s.render;
    settings.integrator = type;
    settings.spp = 16;
    // Every sample is the same: the only light is a delta, seen unoccluded from every point.
    const testing::Estimate e = testing::image_estimate(s, settings);
    EXPECT_NEAR(e.mean, 0.5 / kPiD * 4.0 * std::cos(a), 1e-4) << integrator_name(type);
  }
  const Lights l(std::move(s));
  // A sun is sampled at every vertex, never chosen among the other lights.
  EXPECT_EQ(l.set.size(), 0u);
  ASSERT_EQ(l.set.always_sampled().size(), 1u);
  LightSample ls;
  ASSERT_TRUE(std::get<DeltaDirectionalLight>(l.set.always_sampled()[0])
                  .sample(Vec3(0.3f, 0.f, 0.2f), 1.f, 0.1f, 0.9f, ls));
  EXPECT_TRUE(ls.delta);
  EXPECT_TRUE(ls.infinite);
  EXPECT_NEAR(ls.wi.x, -std::sin(a), 1e-6);
  EXPECT_EQ(ls.radiance, Vec3(2.f, 4.f, 1.f));
}

// A product shot's lighting: a sun and a uniform sky over an open diffuse quad. Each vertex
// samples the sun and leaves the sky to its BSDF ray, which finds it with weight 1: every sample
// is the exact answer, albedo x sky + albedo / pi x irradiance x cos. (When the sun and the sky
// took turns for one light sample, half the samples missed the sun: noise on an easy image.)
TEST(DirectionalLightTest, ASunAndAUniformSkyOverAnOpenSurfaceAreExactAtEverySample) {
  Scene s = quad_scene(0.5f);
  const double a = 35.0 * kPiD / 180.0;
  s.directional_lights.push_back(
      {Vec3(float(std::sin(a)), float(-std::cos(a)), 0.f), Vec3(2.f, 4.f, 1.f)});
  EnvironmentMap sky;
  sky.scale = Vec3(0.5f, 2.f, 1.f);
  s.environment = sky;
  const double expected = 0.5 * 2.0 + 0.5 / kPiD * 4.0 * std::cos(a);  // green
  for (const IntegratorType type : {IntegratorType::kNee, IntegratorType::kMis}) {
    RenderSettings settings = s.render;
    settings.integrator = type;
    settings.spp = 64;
    settings.roulette_depth = 8;  // no roulette at the one bounce
    const testing::Estimate e = testing::image_estimate(s, settings);
    EXPECT_NEAR(e.mean, expected, 1e-5 * expected) << integrator_name(type);
    EXPECT_LE(e.standard_error, 1e-6 * expected) << integrator_name(type) << ": noise";
  }
  const Lights l(std::move(s));
  EXPECT_TRUE(l.set.environment_unsampled());
  EXPECT_EQ(l.set.environment_index(), -1);
  EXPECT_EQ(l.set.environment_pdf(Vec3(0.f, 1.f, 0.f)), 0.f);
}

}  // namespace
}  // namespace rayfarm
