// The Sobol' sampler renders the same expected image as the independent one, with less noise.
//
// Unbiasedness: per pixel, D = (Sobol' estimate) - (independent estimate) at the same spp. Every
// pixel's samples are keyed by the pixel, so the pixels' D are independent, and if both samplers
// are unbiased every D has mean 0 whatever the image shows. Per 16 x 16 block and channel, the
// mean of the 256 D's over their standard error (from their own spread) is then close to
// standard normal; each is held below the Bonferroni bound for all comparisons of the test at
// an overall false-alarm rate of 1e-3.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>

#include "common/image/fixed.h"
#include "common/scene/parser.h"
#include "test_scenes.h"
#include "tests/support/normal_quantile.h"
#include "worker/renderer.h"

namespace rayfarm {
namespace {

const std::string kScenes = std::string(RAYFARM_SOURCE_DIR) + "/scenes/";

struct Case {
  std::string name;
  Scene scene;
};

std::vector<float> pixel_means(const Scene& scene, RenderSettings settings, SamplerType sampler,
                               uint64_t seed) {
  settings.sampler = sampler;
  settings.seed = seed;
  const Renderer renderer(scene, settings);
  const TileResult r =
      renderer.render({0, 0, scene.film.width, scene.film.height}, {0, settings.spp});
  EXPECT_EQ(r.nonfinite, 0u);
  std::vector<float> out(r.sum.size());
  for (size_t i = 0; i < out.size(); ++i) out[i] = float(from_fixed(r.sum[i]) / settings.spp);
  return out;
}

std::vector<Case> cases() {
  std::vector<Case> out;
  Scene cornell = load_scene(kScenes + "cornell-box/scene.json");
  cornell.film = {64, 64};
  out.push_back({"cornell-box", cornell});
  Scene textured = load_scene(kScenes + "textured/scene.json");
  textured.film = {64, 48};
  out.push_back({"textured", textured});
  Scene sky = load_scene(kScenes + "environment/scene.json");
  sky.film = {64, 48};
  out.push_back({"environment", sky});
  out.push_back({"small room (point light, glass, mirror)", testing::small_room_scene(64, 48)});
  return out;
}

TEST(SobolSampler, RendersTheSameExpectedImageAsIndependentSamples) {
  const uint32_t block = 16;
  const std::vector<Case> all = cases();
  size_t comparisons = 0;
  for (const Case& c : all)
    comparisons += size_t{c.scene.film.width / block} * (c.scene.film.height / block) * 3;
  const double z_max = testing::two_sided_z(1e-3 / double(comparisons));
  for (const Case& c : all) {
    RenderSettings settings = c.scene.render;
    settings.spp = 16;
    const std::vector<float> a = pixel_means(c.scene, settings, SamplerType::kSobol, 5);
    const std::vector<float> b = pixel_means(c.scene, settings, SamplerType::kIndependent, 6);
    const uint32_t w = c.scene.film.width;
    for (uint32_t by = 0; by + block <= c.scene.film.height; by += block) {
      for (uint32_t bx = 0; bx + block <= w; bx += block) {
        for (int ch = 0; ch < 3; ++ch) {
          double s = 0.0, s2 = 0.0;
          for (uint32_t y = by; y < by + block; ++y) {
            for (uint32_t x = bx; x < bx + block; ++x) {
              const size_t i = (size_t{y} * w + x) * 3 + ch;
              const double d = double(a[i]) - double(b[i]);
              s += d;
              s2 += d * d;
            }
          }
          const double n = double(block) * block, mean = s / n;
          const double se = std::sqrt(std::max(0.0, (s2 / n - mean * mean) / (n - 1.0)));
          if (se == 0.0) {
            EXPECT_EQ(mean, 0.0) << c.name << " block " << bx << "," << by;
            continue;
          }
          EXPECT_LT(std::fabs(mean / se), z_max)
              << c.name << ": block at " << bx << "," << by << " channel " << ch
              << ": mean difference " << mean << " (standard error " << se << ")";
        }
      }
    }
  }
}

// Per-pixel variance of an estimate at `spp`, averaged over the image: half the mean squared
// difference between two renders of different seeds.
double mean_pixel_variance(const Scene& scene, RenderSettings settings, SamplerType sampler) {
  const std::vector<float> a = pixel_means(scene, settings, sampler, 21);
  const std::vector<float> b = pixel_means(scene, settings, sampler, 22);
  double s = 0.0;
  for (size_t i = 0; i < a.size(); ++i) s += 0.5 * (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
  return s / double(a.size());
}

TEST(SobolSampler, HasLessNoiseThanIndependentSamples) {
  // On the Cornell box (area light, mirror, glass) at 16 spp, the stratified camera, light and
  // first bounces leave clearly less variance per pixel. Each figure averages 12288 pixel
  // channels; its own relative error is a few percent, far below the margin asked for.
  Scene cornell = load_scene(kScenes + "cornell-box/scene.json");
  cornell.film = {64, 64};
  RenderSettings settings = cornell.render;
  settings.spp = 16;
  const double sobol = mean_pixel_variance(cornell, settings, SamplerType::kSobol);
  const double independent = mean_pixel_variance(cornell, settings, SamplerType::kIndependent);
  std::cout << "per-pixel variance at 16 spp: sobol " << sobol << ", independent " << independent
            << " (ratio " << sobol / independent << ")\n";
  EXPECT_LT(sobol, 0.8 * independent);
}

}  // namespace
}  // namespace rayfarm
