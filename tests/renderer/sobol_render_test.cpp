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
#include "mc_stats.h"
#include "test_scenes.h"
#include "renderer/renderer.h"

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
  return testing::pixel_means(r, settings.spp);
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
    comparisons += testing::blocks_compared(c.scene.film.width, c.scene.film.height, block);
  const double z_max = testing::bonferroni_z(comparisons);
  for (const Case& c : all) {
    RenderSettings settings = c.scene.render;
    settings.spp = 16;
    const std::vector<float> a = pixel_means(c.scene, settings, SamplerType::kSobol, 5);
    const std::vector<float> b = pixel_means(c.scene, settings, SamplerType::kIndependent, 6);
    testing::expect_same_expectation(a, b, c.scene.film.width, c.scene.film.height, block, z_max,
                                     c.name);
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
