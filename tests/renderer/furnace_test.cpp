// Furnace: a closed sphere of albedo rho whose surface emits Le everywhere. The radiance in
// every direction is Le / (1 - rho) exactly; each integrator must find it within its own
// statistical error.
#include <gtest/gtest.h>

#include <cmath>

#include "test_scenes.h"
#include "renderer/renderer.h"

namespace rayfarm {
namespace {

struct Estimate {
  double mean = 0.0;
  double standard_error = 0.0;
  uint64_t nonfinite = 0;
};

// Mean over pixels of each pixel's mean (green), with its standard error from the spread of the
// pixel means: every pixel's samples (Sobol' points or a stream) are keyed by the pixel, so
// pixels are independent replicas of one estimator, and in a furnace they share its expectation.
Estimate estimate_by_pixels(const Scene& scene, const RenderSettings& settings) {
  Renderer renderer(scene, settings);
  const TileResult r = renderer.render({0, 0, scene.film.width, scene.film.height}, {0, settings.spp});
  const double n = double(r.rect.pixel_count());
  double sum = 0.0, sum_sq = 0.0;
  for (size_t p = 0; p < r.rect.pixel_count(); ++p) {
    const double m = from_fixed(r.sum[p * 3 + 1]) / settings.spp;
    sum += m;
    sum_sq += m * m;
  }
  Estimate e;
  e.mean = sum / n;
  e.standard_error = std::sqrt(std::max(0.0, (sum_sq / n - e.mean * e.mean) / (n - 1.0)));
  e.nonfinite = r.nonfinite;
  return e;
}

class FurnaceTest : public ::testing::TestWithParam<IntegratorType> {};

TEST_P(FurnaceTest, RadianceIsLeOverOneMinusAlbedo) {
  const float rho = 0.5f, le = 1.f;
  const Scene scene = testing::furnace_scene(rho, le);
  RenderSettings settings = scene.render;
  settings.integrator = GetParam();
  settings.spp = 256;
  settings.seed = 7;
  const Estimate e = estimate_by_pixels(scene, settings);
  const double expected = le / (1.0 - rho);
  // 5 standard errors: a false alarm has probability below 1e-6 per integrator.
  EXPECT_NEAR(e.mean, expected, 5.0 * e.standard_error)
      << integrator_name(GetParam()) << ": standard error " << e.standard_error;
  EXPECT_GT(e.standard_error, 0.0);
  EXPECT_LT(e.standard_error, 0.02 * expected) << "too few samples for a meaningful test";
  EXPECT_EQ(e.nonfinite, 0u);
}

INSTANTIATE_TEST_SUITE_P(AllIntegrators, FurnaceTest,
                         ::testing::Values(IntegratorType::kNaive, IntegratorType::kNee,
                                           IntegratorType::kMis),
                         [](const auto& test_info) { return std::string(integrator_name(test_info.param)); });

struct NoCapCase {
  IntegratorType integrator;
  RouletteType roulette;
  SamplerType sampler;
};

class NearlyWhiteFurnace : public ::testing::TestWithParam<NoCapCase> {};

TEST_P(NearlyWhiteFurnace, WithoutADepthCapReadsItsExactValue) {
  // Albedo 0.999: Le / (1 - rho) = 1000, of which a cap of 1024 vertices would cut
  // rho^1025 = 36%. Paths average about 1000 vertices; roulette alone ends them.
  const float rho = 0.999f, le = 1.f;
  Scene scene = testing::furnace_scene(rho, le);
  scene.film = {16, 16};
  RenderSettings settings = scene.render;
  settings.max_depth = kUnlimitedDepth;
  settings.integrator = GetParam().integrator;
  settings.roulette = GetParam().roulette;
  settings.sampler = GetParam().sampler;
  settings.spp = 32;
  settings.seed = 11;
  const Estimate e = estimate_by_pixels(scene, settings);
  const double expected = le / (1.0 - double(rho));
  // 5 standard errors: a false alarm has probability below 1e-6 per case (the mean of 256
  // independent pixel means is close to normal).
  EXPECT_NEAR(e.mean, expected, 5.0 * e.standard_error) << "standard error " << e.standard_error;
  EXPECT_LT(e.standard_error, 0.03 * expected) << "too few samples for a meaningful test";
  EXPECT_GT(5.0 * e.standard_error, 0.0);
  EXPECT_LT(5.0 * e.standard_error, 0.36 * expected) << "could not tell a cap of 1024 vertices";
  EXPECT_EQ(e.nonfinite, 0u);
}

INSTANTIATE_TEST_SUITE_P(
    NoCap, NearlyWhiteFurnace,
    ::testing::Values(
        NoCapCase{IntegratorType::kNaive, RouletteType::kRoot, SamplerType::kSobol},
        NoCapCase{IntegratorType::kNee, RouletteType::kRoot, SamplerType::kSobol},
        NoCapCase{IntegratorType::kMis, RouletteType::kRoot, SamplerType::kSobol},
        NoCapCase{IntegratorType::kMis, RouletteType::kThroughput, SamplerType::kSobol},
        NoCapCase{IntegratorType::kMis, RouletteType::kUpdate, SamplerType::kSobol},
        NoCapCase{IntegratorType::kMis, RouletteType::kRoot, SamplerType::kIndependent}),
    [](const auto& test_info) {
      const NoCapCase& c = test_info.param;
      return std::string(integrator_name(c.integrator)) + "_" + roulette_name(c.roulette) + "_" +
             sampler_name(c.sampler);
    });

TEST(FurnaceDepthCap, TruncatedSumMatchesGeometricSeries) {
  // With max_depth D the estimator sums D + 1 terms: Le * (1 - rho^(D+1)) / (1 - rho).
  const float rho = 0.5f, le = 1.f;
  Scene scene = testing::furnace_scene(rho, le);
  for (uint32_t depth : {0u, 1u, 3u}) {
    RenderSettings settings = scene.render;
    settings.integrator = IntegratorType::kNee;
    settings.max_depth = depth;
    settings.spp = 256;
    const Estimate e = estimate_by_pixels(scene, settings);
    const double expected = le * (1.0 - std::pow(rho, depth + 1)) / (1.0 - rho);
    // Inside a sphere cos*cos/d^2 is constant, so NEE's direct term has zero variance: allow for
    // float32 rounding (1e-6 relative) on top of 5 standard errors.
    EXPECT_NEAR(e.mean, expected, 5.0 * e.standard_error + 1e-6 * expected) << "max_depth " << depth;
  }
}

}  // namespace
}  // namespace rayfarm
