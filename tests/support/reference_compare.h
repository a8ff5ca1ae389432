#pragma once
// Our render against a reference image with known per-pixel variance (a Blender Cycles render made
// of several independent renders), per 8x8 block and channel:
//   z = (ours - reference) / sqrt(var_ours + var_reference),
// where var_ours is the variance of our block mean from the film's exact per-pixel sums
// (sum_sq - sum^2/n) / (n (n - 1)), and var_reference that of the reference's block mean from its
// variance image. Two-sided, Bonferroni-corrected over every block value and the 3 whole-image
// channel means, at a family-wise error of 1e-3. Per channel, the sum of z^2 over the
// (independent) blocks is checked against its chi-square distribution: a small bias spread over
// many blocks shows there before any single block fails.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <string>
#include <vector>

#include "common/image/exr.h"
#include "common/image/film.h"
#include "common/scene/scene.h"
#include "tests/support/normal_quantile.h"

namespace rayfarm::testing {

constexpr uint32_t kReferenceBlock = 8;

/// What every Cycles reference must satisfy against the scene it was made for: the film's size,
/// the path length (Cycles bounces = max_depth - 1), the box filter of width 1, the settings
/// identical in both EXR headers and the sidecar `meta`, and the image means the script computed
/// (no colour transform or half floats on the way).
inline void expect_reference_matches(const Scene& scene, const Image& ref, const Image& var,
                                     const nlohmann::json& meta) {
  EXPECT_EQ(ref.width, scene.film.width);
  EXPECT_EQ(ref.height, scene.film.height);
  EXPECT_EQ(var.width, scene.film.width);
  EXPECT_EQ(var.height, scene.film.height);
  EXPECT_EQ(meta.at("our_max_depth").get<uint32_t>(), scene.render.max_depth);
  EXPECT_EQ(meta.at("cycles").at("max_bounces").get<uint32_t>(), scene.render.max_depth - 1);
  EXPECT_EQ(meta.at("cycles").at("pixel_filter_type").get<std::string>(), "BOX");
  EXPECT_EQ(meta.at("cycles").at("filter_width").get<double>(), 1.0);
  ASSERT_TRUE(ref.attributes.count("rayfarmReference")) << "no settings in the EXR header";
  ASSERT_TRUE(var.attributes.count("rayfarmReference")) << "no settings in the variance header";
  EXPECT_EQ(ref.attributes.at("rayfarmReference"), var.attributes.at("rayfarmReference"));
  const nlohmann::json header = nlohmann::json::parse(ref.attributes.at("rayfarmReference"));
  EXPECT_EQ(header.at("cycles"), meta.at("cycles"));
  for (int c = 0; c < 3; ++c) {
    double sum = 0.0;
    for (size_t p = 0; p < size_t{ref.width} * ref.height; ++p) sum += ref.rgb[p * 3 + c];
    const double expected = meta.at("image_mean_rgb").at(c).get<double>();
    EXPECT_NEAR(sum / (double(ref.width) * ref.height), expected, 1e-6 * expected)
        << "channel " << c;
  }
}

/// Per block (row-major) and channel: a mean and the variance of that mean.
struct Blocks {
  uint32_t bw = 0, bh = 0;
  std::vector<double> mean, var;
  double image_mean[3] = {0, 0, 0}, image_var[3] = {0, 0, 0};
};

// Pixels are independent, so the variance of an average of P pixels is the sum of their
// variances / P^2.
inline Blocks reduce_to_blocks(const std::vector<double>& mean, const std::vector<double>& var,
                               uint32_t w, uint32_t h) {
  Blocks b;
  b.bw = w / kReferenceBlock;
  b.bh = h / kReferenceBlock;
  b.mean.assign(size_t{b.bw} * b.bh * 3, 0.0);
  b.var.assign(b.mean.size(), 0.0);
  const double per_block = double(kReferenceBlock) * kReferenceBlock, per_image = double(w) * h;
  for (uint32_t y = 0; y < b.bh * kReferenceBlock; ++y) {
    for (uint32_t x = 0; x < b.bw * kReferenceBlock; ++x) {
      const size_t blk = (size_t{y / kReferenceBlock} * b.bw + x / kReferenceBlock) * 3;
      for (int c = 0; c < 3; ++c) {
        const size_t i = (size_t{y} * w + x) * 3 + c;
        b.mean[blk + c] += mean[i] / per_block;
        b.var[blk + c] += var[i] / (per_block * per_block);
      }
    }
  }
  for (size_t p = 0; p < size_t{w} * h; ++p) {
    for (int c = 0; c < 3; ++c) {
      b.image_mean[c] += mean[p * 3 + c] / per_image;
      b.image_var[c] += var[p * 3 + c] / (per_image * per_image);
    }
  }
  return b;
}

/// Our film's per-pixel means and variances of the mean, reduced to blocks.
inline Blocks film_blocks(const Film& film, uint32_t w, uint32_t h) {
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
  return reduce_to_blocks(mean, var, w, h);
}

/// A reference image and the image of its per-pixel variance of the mean, reduced to blocks.
inline Blocks exr_blocks(const std::string& mean_path, const std::string& var_path) {
  const Image ref = read_exr(mean_path);
  const Image var = read_exr(var_path);
  EXPECT_EQ(ref.width, var.width);
  EXPECT_EQ(ref.height, var.height);
  return reduce_to_blocks(std::vector<double>(ref.rgb.begin(), ref.rgb.end()),
                          std::vector<double>(var.rgb.begin(), var.rgb.end()), ref.width,
                          ref.height);
}

/// The figures of one comparison, for the test's output and for tests that assert on them.
struct Agreement {
  double max_abs_z = 0.0, z_limit = 0.0;
  double chi2[3] = {0, 0, 0}, chi2_limit[3] = {0, 0, 0};
  double z_image[3] = {0, 0, 0};
};

/// Expects `ours` to agree with `ref` block by block, in the whole-image means, and in the
/// chi-square sum of each channel; prints the figures under `label`.
inline Agreement expect_agreement(const Blocks& ours, const Blocks& ref, const std::string& label) {
  Agreement out;
  EXPECT_EQ(ours.mean.size(), ref.mean.size()) << label;
  if (ours.mean.size() != ref.mean.size()) return out;
  const size_t blocks = ours.mean.size() / 3;
  out.z_limit = two_sided_z(1e-3 / double(ours.mean.size() + 3));
  double ref_share = 0.0;
  size_t shared = 0;
  for (int c = 0; c < 3; ++c) {
    double chi2 = 0.0;
    size_t compared = 0;
    std::string map;  // the z of every block, printed when something fails
    for (size_t b = 0; b < blocks; ++b) {
      const size_t i = b * 3 + c;
      const double var = ours.var[i] + ref.var[i];
      double z = 0.0;
      if (var == 0.0) {
        EXPECT_EQ(ours.mean[i], ref.mean[i])
            << label << ": block " << b << " is black in one image only";
      } else {
        z = (ours.mean[i] - ref.mean[i]) / std::sqrt(var);
        EXPECT_LT(std::fabs(z), out.z_limit)
            << label << ": block (" << b % ours.bw << ", " << b / ours.bw << ") channel " << c
            << ": ours " << ours.mean[i] << " reference " << ref.mean[i] << " se "
            << std::sqrt(var);
        chi2 += z * z;
        out.max_abs_z = std::max(out.max_abs_z, std::fabs(z));
        ref_share += ref.var[i] / var;
        ++shared;
        ++compared;
      }
      map += (b % ours.bw == 0 ? "\n  " : " ") + std::to_string(z).substr(0, z < 0 ? 5 : 4);
    }
    EXPECT_GT(compared, blocks / 2) << label << ": too few blocks with any light";
    // Upper 1e-3 / 3 point of chi-square(compared) by the Wilson-Hilferty approximation (z = 3.29).
    const double k = double(compared), a = 2.0 / (9.0 * k);
    out.chi2[c] = chi2;
    out.chi2_limit[c] = k * std::pow(1.0 - a + 3.29 * std::sqrt(a), 3.0);
    const double se = std::sqrt(ours.image_var[c] + ref.image_var[c]);
    out.z_image[c] = (ours.image_mean[c] - ref.image_mean[c]) / se;
    std::cout << label << " channel " << c << ": image mean ours " << ours.image_mean[c]
              << " reference " << ref.image_mean[c] << " (ratio "
              << ours.image_mean[c] / ref.image_mean[c] << ", z " << out.z_image[c]
              << "); blocks: sum z^2 " << chi2 << " for " << compared << " (limit "
              << out.chi2_limit[c] << ")\n";
    EXPECT_LT(std::fabs(out.z_image[c]), out.z_limit) << label << ": whole image, channel " << c;
    EXPECT_LT(chi2, out.chi2_limit[c]) << label << ": channel " << c << ", z per block:" << map;
  }
  std::cout << label << ": max |z| " << out.max_abs_z << " (limit " << out.z_limit
            << "); the reference's share of the variance "
            << ref_share / double(std::max<size_t>(shared, 1)) << "\n";
  return out;
}

}  // namespace rayfarm::testing
