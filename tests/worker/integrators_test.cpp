// The three integrators estimate the same integral: on the bundled Cornell box (area light,
// mirror, glass) their images must agree within their own statistical error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "common/scene/parser.h"
#include "worker/renderer.h"

namespace rayfarm {
namespace {

struct BlockStats {
  std::vector<double> mean, variance_of_mean;  // per block and channel
};

// Renders `spp` samples and reduces them to block x block pixel blocks: the mean radiance of
// each block and the variance of that mean, from the per-sample second moments.
BlockStats render_blocks(const Scene& scene, IntegratorType integrator, uint32_t spp, uint32_t block) {
  RenderSettings settings = scene.render;
  settings.integrator = integrator;
  settings.spp = spp;
  settings.seed = 1000 + static_cast<uint64_t>(integrator);  // independent estimates
  Renderer renderer(scene, settings);
  const TileResult r = renderer.render({0, 0, scene.film.width, scene.film.height}, {0, spp});
  EXPECT_EQ(r.nonfinite, 0u);
  const uint32_t bw = scene.film.width / block, bh = scene.film.height / block;
  BlockStats stats;
  stats.mean.assign(size_t{bw} * bh * 3, 0.0);
  stats.variance_of_mean.assign(size_t{bw} * bh * 3, 0.0);
  const double n = double(block) * block * spp;
  for (uint32_t by = 0; by < bh; ++by) {
    for (uint32_t bx = 0; bx < bw; ++bx) {
      for (int c = 0; c < 3; ++c) {
        double s = 0.0, s2 = 0.0;
        for (uint32_t y = by * block; y < (by + 1) * block; ++y) {
          for (uint32_t x = bx * block; x < (bx + 1) * block; ++x) {
            const size_t i = (size_t{y} * scene.film.width + x) * 3 + c;
            s += from_fixed(r.sum[i]);
            s2 += from_fixed(r.sum_sq[i]);
          }
        }
        const double mean = s / n;
        const size_t b = (size_t{by} * bw + bx) * 3 + c;
        stats.mean[b] = mean;
        stats.variance_of_mean[b] = std::max(0.0, s2 / n - mean * mean) / (n - 1.0);
      }
    }
  }
  return stats;
}

TEST(Integrators, AgreeOnTheCornellBoxWithinTheirStatisticalError) {
  Scene scene = load_scene(std::string(RAYFARM_SOURCE_DIR) + "/scenes/cornell-box/scene.json");
  scene.film = {32, 32};
  const uint32_t block = 8;
  const BlockStats mis = render_blocks(scene, IntegratorType::kMis, 256, block);
  const BlockStats nee = render_blocks(scene, IntegratorType::kNee, 256, block);
  const BlockStats naive = render_blocks(scene, IntegratorType::kNaive, 1024, block);
  // Two-sided z-test per block and channel; Bonferroni over all comparisons at 1e-3 overall:
  // 2 pairs x 48 values -> per test p = 1e-5, |z| < 4.42.
  const double z_max = 4.42;
  int compared = 0;
  for (size_t b = 0; b < mis.mean.size(); ++b) {
    for (const BlockStats* other : {&nee, &naive}) {
      const double se = std::sqrt(mis.variance_of_mean[b] + other->variance_of_mean[b]);
      if (se == 0.0) {
        EXPECT_EQ(mis.mean[b], other->mean[b]);
        continue;
      }
      const double z = (mis.mean[b] - other->mean[b]) / se;
      EXPECT_LT(std::fabs(z), z_max) << "block value " << b << ": mis " << mis.mean[b]
                                     << " vs " << other->mean[b] << " (se " << se << ")";
      ++compared;
    }
  }
  EXPECT_GT(compared, 60);
  // MIS must be the better estimator here: lower total variance than naive at equal samples.
  double var_mis = 0.0, var_naive = 0.0;
  for (size_t b = 0; b < mis.mean.size(); ++b) {
    var_mis += mis.variance_of_mean[b] * 256.0;
    var_naive += naive.variance_of_mean[b] * 1024.0;
  }
  EXPECT_LT(var_mis, var_naive);
}

// Every bundled scene loads, renders at a few samples without a NaN, and is not black.
class BundledScene : public ::testing::TestWithParam<const char*> {};

TEST_P(BundledScene, RendersFiniteNonBlackImage) {
  Scene scene = load_scene(std::string(RAYFARM_SOURCE_DIR) + "/scenes/" + GetParam() + "/scene.json");
  EXPECT_TRUE(scene.warnings.empty());
  scene.film = {24, 24};
  for (IntegratorType integrator : {IntegratorType::kNaive, IntegratorType::kNee, IntegratorType::kMis}) {
    RenderSettings settings = scene.render;
    settings.integrator = integrator;
    settings.spp = 4;
    Renderer renderer(scene, settings);
    const TileResult r = renderer.render({0, 0, 24, 24}, {0, 4});
    EXPECT_EQ(r.nonfinite, 0u) << integrator_name(integrator);
    Fixed total = 0;
    for (Fixed v : r.sum) total += v;
    // BSDF sampling alone cannot reach a point light: a scene lit only by point lights is
    // black under the naive integrator, and must be lit under the others.
    const bool point_lit_only = !scene.point_lights.empty() && std::none_of(
        scene.materials.begin(), scene.materials.end(), [](const Material& m) { return m.is_emissive(); });
    if (integrator == IntegratorType::kNaive && point_lit_only) {
      EXPECT_EQ(total, 0);
    } else {
      EXPECT_GT(total, 0) << integrator_name(integrator);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Scenes, BundledScene,
                         ::testing::Values("cornell-box", "phong", "furnace", "embree-cornell"),
                         [](const auto& test_info) {
                           std::string name = test_info.param;
                           for (char& ch : name) ch = ch == '-' ? '_' : ch;
                           return name;
                         });

}  // namespace
}  // namespace rayfarm
