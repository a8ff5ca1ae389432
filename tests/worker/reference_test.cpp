// Our renderer against an image that no one here wrote: Blender Cycles' render of
// scenes/cornell-blocks (tests/data/references/cornell-blocks-cycles.exr, made by
// scripts/make-references.sh with the settings in cornell-blocks-cycles.json). Cycles finds the
// emitter by BSDF sampling alone there: Blender 3.4.1's mesh-light sampling is biased low near the
// light's plane (up to 6% per block on the upper back wall), while ours and Cycles' BSDF sampling
// both match the exact irradiance of the quad light (tests/data/references/README.md).
//
// Statistics. Both images estimate the same per-pixel integral (box pixel filter, same paths up to
// max_depth scattering vertices). Pixels are reduced to 8x8 blocks; for each block and channel
//   z = (ours - cycles) / sqrt(var_ours + var_cycles),
// where var_ours is the variance of our block mean from the film's exact per-pixel sums
// (sum_sq - sum^2/n) / (n (n - 1)), and var_cycles that of the reference's block mean, estimated
// from the spread of its 8 independent renders (cornell-blocks-cycles-variance.exr). Two-sided,
// with a Bonferroni correction over the 64 blocks x 3 channels plus the 3 whole-image channel
// means, at a family-wise error of 1e-3 per integrator. Per channel, the sum of z^2 over the
// (independent) blocks is checked against its chi-square distribution: a small bias spread over
// many blocks shows there before any single block fails. The renders use fixed seeds, so the test
// is deterministic; the statistics say how unlikely a failure is for a correct renderer.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <iostream>
#include <fstream>
#include <string>

#include "common/image/exr.h"
#include "common/image/film.h"
#include "common/scene/parser.h"
#include "tests/support/normal_quantile.h"
#include "worker/renderer.h"

namespace rayfarm {
namespace {

const std::string kRefDir = std::string(RAYFARM_SOURCE_DIR) + "/tests/data/references/";
const std::string kScene = std::string(RAYFARM_SOURCE_DIR) + "/scenes/cornell-blocks/scene.json";
constexpr uint32_t kBlock = 8;

/// Per block (row-major) and channel: a mean and the variance of that mean.
struct Blocks {
  uint32_t bw = 0, bh = 0;
  std::vector<double> mean, var;
  double image_mean[3] = {0, 0, 0}, image_var[3] = {0, 0, 0};
};

// Reduces per-pixel means and variances of the mean (RGB interleaved) to blocks; pixels are
// independent, so the variance of an average of P pixels is the sum of their variances / P^2.
Blocks reduce(const std::vector<double>& mean, const std::vector<double>& var, uint32_t w, uint32_t h) {
  Blocks b;
  b.bw = w / kBlock;
  b.bh = h / kBlock;
  b.mean.assign(size_t{b.bw} * b.bh * 3, 0.0);
  b.var.assign(b.mean.size(), 0.0);
  const double per_block = double(kBlock) * kBlock, per_image = double(w) * h;
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      const size_t blk = (size_t{y / kBlock} * b.bw + x / kBlock) * 3;
      for (int c = 0; c < 3; ++c) {
        const size_t i = (size_t{y} * w + x) * 3 + c;
        b.mean[blk + c] += mean[i] / per_block;
        b.var[blk + c] += var[i] / (per_block * per_block);
        b.image_mean[c] += mean[i] / per_image;
        b.image_var[c] += var[i] / (per_image * per_image);
      }
    }
  }
  return b;
}

// Our render: per-pixel means and variances of the mean from the film's exact sums.
Blocks render_blocks(const Scene& scene, IntegratorType integrator, uint32_t spp) {
  RenderSettings settings = scene.render;
  settings.integrator = integrator;
  settings.spp = spp;
  settings.seed = 77;
  const Renderer renderer(scene, settings);
  const uint32_t w = scene.film.width, h = scene.film.height;
  Film film(w, h);
  film.add(renderer.render({0, 0, w, h}, {0, spp}));
  EXPECT_EQ(film.nonfinite(), 0u);
  std::vector<double> mean(size_t{w} * h * 3), var(mean.size());
  for (size_t p = 0; p < size_t{w} * h; ++p) {
    const double n = film.spp()[p];
    for (int c = 0; c < 3; ++c) {
      const double s = from_fixed(film.sum()[p * 3 + c]), s2 = from_fixed(film.sum_sq()[p * 3 + c]);
      mean[p * 3 + c] = s / n;
      var[p * 3 + c] = std::max(0.0, s2 - s * s / n) / (n * (n - 1.0));
    }
  }
  return reduce(mean, var, w, h);
}

Blocks reference_blocks() {
  const Image ref = read_exr(kRefDir + "cornell-blocks-cycles.exr");
  const Image var = read_exr(kRefDir + "cornell-blocks-cycles-variance.exr");
  return reduce(std::vector<double>(ref.rgb.begin(), ref.rgb.end()),
                std::vector<double>(var.rgb.begin(), var.rgb.end()), ref.width, ref.height);
}

using testing::two_sided_z;

TEST(CyclesReference, FilesMatchTheSceneAndTheirSettings) {
  const Scene scene = load_scene(kScene);
  const Image ref = read_exr(kRefDir + "cornell-blocks-cycles.exr");
  const Image var = read_exr(kRefDir + "cornell-blocks-cycles-variance.exr");
  std::ifstream in(kRefDir + "cornell-blocks-cycles.json");
  ASSERT_TRUE(in) << "missing settings sidecar";
  const nlohmann::json meta = nlohmann::json::parse(in);
  EXPECT_EQ(ref.width, scene.film.width);
  EXPECT_EQ(ref.height, scene.film.height);
  EXPECT_EQ(var.width, scene.film.width);
  EXPECT_EQ(var.height, scene.film.height);
  // The reference was made for this scene's path length: Cycles bounces = max_depth - 1.
  EXPECT_EQ(meta.at("our_max_depth").get<uint32_t>(), scene.render.max_depth);
  EXPECT_EQ(meta.at("cycles").at("max_bounces").get<uint32_t>(), scene.render.max_depth - 1);
  EXPECT_EQ(meta.at("cycles").at("pixel_filter_type").get<std::string>(), "BOX");
  EXPECT_EQ(meta.at("cycles").at("filter_width").get<double>(), 1.0);
  // The settings are in both headers too, identical.
  ASSERT_TRUE(ref.attributes.count("rayfarmReference")) << "no settings in the EXR header";
  EXPECT_EQ(ref.attributes.at("rayfarmReference"), var.attributes.at("rayfarmReference"));
  const nlohmann::json header = nlohmann::json::parse(ref.attributes.at("rayfarmReference"));
  EXPECT_EQ(header.at("cycles"), meta.at("cycles"));
  EXPECT_EQ(header.at("seeds"), meta.at("seeds"));
  // The EXR holds what the script computed (no colour transform or half floats on the way).
  for (int c = 0; c < 3; ++c) {
    double sum = 0.0;
    for (size_t p = 0; p < size_t{ref.width} * ref.height; ++p) sum += ref.rgb[p * 3 + c];
    const double expected = meta.at("image_mean_rgb").at(c).get<double>();
    EXPECT_NEAR(sum / (double(ref.width) * ref.height), expected, 1e-6 * expected) << "channel " << c;
  }
}

class AgainstCycles : public ::testing::TestWithParam<IntegratorType> {};

TEST_P(AgainstCycles, AgreesPerBlockWithinStatisticalError) {
  const Scene scene = load_scene(kScene);
  const Blocks ref = reference_blocks();
  // Naive finds the small light by BSDF sampling alone: at a few hundred spp a block next to the
  // light can miss its rare bright paths, and then both its mean and its sample variance come out
  // low (seed 2 at 384 spp: z = -5 in one block). From about 1024 spp the block means are close
  // enough to normal: over seeds 1-14 the largest |z| was 3.3 and every sum of z^2 within limits.
  const uint32_t spp = GetParam() == IntegratorType::kNaive ? 1024 : 256;
  const Blocks ours = render_blocks(scene, GetParam(), spp);
  ASSERT_EQ(ours.mean.size(), ref.mean.size());
  const size_t blocks = ours.mean.size() / 3;

  // Family-wise error 1e-3: Bonferroni over every block value and the 3 image means.
  const double z_max = two_sided_z(1e-3 / double(ours.mean.size() + 3));
  double worst = 0.0, ref_share = 0.0;
  for (int c = 0; c < 3; ++c) {
    double chi2 = 0.0;
    size_t compared = 0;
    std::string map;  // the z of every block, printed when something fails
    for (size_t b = 0; b < blocks; ++b) {
      const size_t i = b * 3 + c;
      const double var = ours.var[i] + ref.var[i];
      double z = 0.0;
      if (var == 0.0) {
        EXPECT_EQ(ours.mean[i], ref.mean[i]) << "block " << b << " is black in one image only";
      } else {
        z = (ours.mean[i] - ref.mean[i]) / std::sqrt(var);
        EXPECT_LT(std::fabs(z), z_max) << "block (" << b % ours.bw << ", " << b / ours.bw << ") channel "
                                       << c << ": ours " << ours.mean[i] << " cycles " << ref.mean[i]
                                       << " se " << std::sqrt(var);
        chi2 += z * z;
        worst = std::max(worst, std::fabs(z));
        ref_share += ref.var[i] / var;
        ++compared;
      }
      map += (b % ours.bw == 0 ? "\n  " : " ") + std::to_string(z).substr(0, z < 0 ? 5 : 4);
    }
    ASSERT_GT(compared, blocks / 2);
    // The blocks of one channel are independent: sum z^2 ~ chi-square(compared). Its upper
    // 1e-3 / 3 point by the Wilson-Hilferty approximation (z = 3.29) catches a small bias spread
    // over many blocks that the per-block test misses.
    const double k = double(compared), a = 2.0 / (9.0 * k);
    const double chi2_max = k * std::pow(1.0 - a + 3.29 * std::sqrt(a), 3.0);
    const double se = std::sqrt(ours.image_var[c] + ref.image_var[c]);
    const double z_image = (ours.image_mean[c] - ref.image_mean[c]) / se;
    std::cout << integrator_name(GetParam()) << " channel " << c << ": image mean ours "
              << ours.image_mean[c] << " cycles " << ref.image_mean[c] << " (ratio "
              << ours.image_mean[c] / ref.image_mean[c] << ", z " << z_image << "); blocks: sum z^2 "
              << chi2 << " for " << compared << " (limit " << chi2_max << ")\n";
    EXPECT_LT(std::fabs(z_image), z_max) << "whole image, channel " << c;
    EXPECT_LT(chi2, chi2_max) << "channel " << c << ", z per block:" << map;
  }
  std::cout << integrator_name(GetParam()) << ": max |z| " << worst << " (limit " << z_max
            << "); the reference's share of the variance " << ref_share / double(ours.mean.size())
            << "\n";
}

INSTANTIATE_TEST_SUITE_P(Integrators, AgainstCycles,
                         ::testing::Values(IntegratorType::kNaive, IntegratorType::kNee,
                                           IntegratorType::kMis),
                         [](const auto& test_info) { return std::string(integrator_name(test_info.param)); });

}  // namespace
}  // namespace rayfarm
