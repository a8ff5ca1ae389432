// The three integrators estimate the same integral: on the bundled Cornell box (area light,
// mirror, glass) their images must agree within their own statistical error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "tests/renderer/mc_stats.h"
#include "renderer/renderer.h"

namespace rayfarm {
namespace {

TEST(Integrators, AgreeOnTheCornellBoxWithinTheirStatisticalError) {
  Scene scene = load_scene(std::string(RAYFARM_SOURCE_DIR) + "/scenes/cornell-box/scene.json");
  scene.film = {32, 32};
  const uint32_t block = 8;
  // Independent estimates: each integrator with a seed of its own.
  const auto render = [&](IntegratorType integrator, uint32_t spp) {
    return testing::render_blocks(scene, integrator, spp, 1000 + static_cast<uint64_t>(integrator),
                                  block);
  };
  const testing::BlockStats mis = render(IntegratorType::kMis, 256);
  const testing::BlockStats nee = render(IntegratorType::kNee, 256);
  const testing::BlockStats naive = render(IntegratorType::kNaive, 1024);
  for (const testing::BlockStats* s : {&mis, &nee, &naive}) EXPECT_EQ(s->nonfinite, 0u);
  // Two-sided z-test per block and channel, Bonferroni-corrected over both pairs (mc_stats.h).
  const size_t family = 2 * mis.mean.size();
  const size_t compared = testing::expect_same_within_noise(mis, nee, "mis vs nee", family) +
                          testing::expect_same_within_noise(mis, naive, "mis vs naive", family);
  EXPECT_GT(compared, 60u);
  // MIS must be the better estimator here: lower total variance than naive at equal samples.
  double var_mis = 0.0, var_naive = 0.0;
  for (size_t b = 0; b < mis.mean.size(); ++b) {
    var_mis += mis.variance_of_mean[b] * 256.0;
    var_naive += naive.variance_of_mean[b] * 1024.0;
  }
  EXPECT_LT(var_mis, var_naive);
}

// Every bundled scene loads, renders at a few samples without a NaN, and is not black.
class BundledScene : public ::testing::TestWithParam<std::string> {};

TEST_P(BundledScene, RendersFiniteNonBlackImage) {
  Scene scene =
      load_scene(std::string(RAYFARM_SOURCE_DIR) + "/scenes/" + GetParam() + "/scene.json");
  EXPECT_TRUE(scene.warnings.empty());
  scene.film = {24, 24};
  add_motion(scene, scene.render);  // a scene with an open shutter blurs what moves
  EXPECT_TRUE(scene.warnings.empty());
  for (IntegratorType integrator :
       {IntegratorType::kNaive, IntegratorType::kNee, IntegratorType::kMis}) {
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
    const bool point_lit_only = !scene.point_lights.empty() &&
                                std::none_of(scene.materials.begin(), scene.materials.end(),
                                             [](const Material& m) { return m.is_emissive(); });
    if (integrator == IntegratorType::kNaive && point_lit_only) {
      EXPECT_EQ(total, 0);
    } else {
      EXPECT_GT(total, 0) << integrator_name(integrator);
    }
  }
}

/// Every folder of scenes/ with a scene.json: a scene added there is rendered here too.
std::vector<std::string> bundled_scene_names() {
  std::vector<std::string> names;
  for (const auto& entry :
       std::filesystem::directory_iterator(std::filesystem::path(RAYFARM_SOURCE_DIR) / "scenes")) {
    if (std::filesystem::exists(entry.path() / "scene.json"))
      names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

TEST(BundledScenes, AllAreFound) {
  const std::vector<std::string> names = bundled_scene_names();
  for (const char* expected :
       {"cornell-box", "materials", "textured", "environment", "product", "material-preview"})
    EXPECT_NE(std::find(names.begin(), names.end(), expected), names.end()) << expected;
}

INSTANTIATE_TEST_SUITE_P(Scenes, BundledScene, ::testing::ValuesIn(bundled_scene_names()),
                         [](const auto& test_info) {
                           std::string name = test_info.param;
                           for (char& ch : name) ch = ch == '-' ? '_' : ch;
                           return name;
                         });

}  // namespace
}  // namespace rayfarm
