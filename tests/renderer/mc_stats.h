#pragma once
// Statistics of Monte Carlo renders for tests: means with standard errors computed from the
// per-sample second moments that every TileResult carries, and per-block z-tests corrected for
// the number of comparisons (Bonferroni). No tolerance in these tests is guessed: each is a
// number of standard errors computed from the render itself.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "tests/support/normal_quantile.h"
#include "renderer/renderer.h"

namespace rayfarm::testing {

/// A mean over samples and its standard error.
struct Estimate {
  double mean = 0.0;
  double standard_error = 0.0;
  uint64_t nonfinite = 0;
  RenderStats stats;
};

/// The whole image rendered as `rayfarm render` does, with these threads, tile size and pass size.
inline Film render_with(const Renderer& renderer, uint32_t threads, uint32_t tile,
                        uint32_t pass_spp) {
  LocalRenderOptions options;
  options.threads = threads;
  options.tile_size = tile;
  options.pass_spp = pass_spp;
  return render_local(renderer, options);
}

/// Renders every pixel of `scene` with `settings` as one unit.
inline TileResult render_all(const Scene& scene, const RenderSettings& settings,
                             RenderStats* stats = nullptr) {
  Renderer renderer(scene, settings);
  return renderer.render({0, 0, scene.film.width, scene.film.height}, {0, settings.spp}, stats);
}

/// Mean of channel `c` over all samples of all pixels, with its standard error from the
/// per-sample second moment. That is the error of the mean for independent samples only, so the
/// render uses the independent sampler whatever `settings` says (the Sobol' sampler's samples
/// within a pixel are not independent; sobol_render_test.cpp and furnace_test.cpp test it with
/// pixels as the independent replicas).
inline Estimate image_estimate(const Scene& scene, RenderSettings settings, int c = 1) {
  settings.sampler = SamplerType::kIndependent;
  Estimate e;
  const TileResult r = render_all(scene, settings, &e.stats);
  double sum = 0.0, sum_sq = 0.0;
  for (size_t p = 0; p < r.rect.pixel_count(); ++p) {
    sum += from_fixed(r.sum[p * 3 + c]);
    sum_sq += from_fixed(r.sum_sq[p * 3 + c]);
  }
  const double n = double(r.rect.pixel_count()) * settings.spp;
  e.mean = sum / n;
  const double variance = std::max(0.0, (sum_sq / n - e.mean * e.mean) * n / (n - 1.0));
  e.standard_error = std::sqrt(variance / n);
  e.nonfinite = r.nonfinite;
  return e;
}

/// Per block (block x block pixels) and channel: the mean radiance and the variance of that mean,
/// from the per-sample second moments: valid for independent samples only (render_blocks()
/// renders them so; sobol_render_test.cpp compares the Sobol' sampler with it).
struct BlockStats {
  std::vector<double> mean, variance_of_mean;
  uint64_t nonfinite = 0;
};

inline BlockStats block_stats(const TileResult& r, uint32_t block) {
  const uint32_t width = r.rect.width(), bw = width / block, bh = r.rect.height() / block;
  const uint32_t spp = r.samples.count();
  BlockStats stats;
  stats.nonfinite = r.nonfinite;
  stats.mean.assign(size_t{bw} * bh * 3, 0.0);
  stats.variance_of_mean.assign(size_t{bw} * bh * 3, 0.0);
  const double n = double(block) * block * spp;
  for (uint32_t by = 0; by < bh; ++by) {
    for (uint32_t bx = 0; bx < bw; ++bx) {
      for (int c = 0; c < 3; ++c) {
        double s = 0.0, s2 = 0.0;
        for (uint32_t y = by * block; y < (by + 1) * block; ++y) {
          for (uint32_t x = bx * block; x < (bx + 1) * block; ++x) {
            const size_t i = (size_t{y} * width + x) * 3 + c;
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

/// Renders `scene` with `integrator`, `spp` and `seed` and the independent sampler, reduced to
/// blocks.
inline BlockStats render_blocks(const Scene& scene, IntegratorType integrator, uint32_t spp,
                                uint64_t seed, uint32_t block) {
  RenderSettings settings = scene.render;
  settings.integrator = integrator;
  settings.spp = spp;
  settings.seed = seed;
  settings.sampler = SamplerType::kIndependent;  // block_stats() needs independent samples
  return block_stats(render_all(scene, settings), block);
}

/// Two-sided z quantile for a family of `comparisons` tests at overall false-alarm rate
/// `alpha` (Bonferroni): per test p = alpha / comparisons.
inline double bonferroni_z(size_t comparisons, double alpha = 1e-3) {
  return two_sided_z(alpha / double(comparisons));
}

/// Expects every block of `a` to equal the same block of `b` within the z bound of `family`
/// comparisons (Bonferroni at 1e-3 overall; by default the comparisons of this call, more when
/// the caller makes several calls as one family). Blocks where both have zero variance must be
/// equal exactly. Returns the number of comparisons made.
inline size_t expect_same_within_noise(const BlockStats& a, const BlockStats& b,
                                       const std::string& what, size_t family = 0) {
  EXPECT_EQ(a.mean.size(), b.mean.size()) << what;
  const double z_max = bonferroni_z(family > 0 ? family : a.mean.size());
  size_t compared = 0;
  for (size_t i = 0; i < a.mean.size() && i < b.mean.size(); ++i) {
    const double se = std::sqrt(a.variance_of_mean[i] + b.variance_of_mean[i]);
    if (se == 0.0) {
      EXPECT_EQ(a.mean[i], b.mean[i]) << what << ": block value " << i;
      continue;
    }
    const double z = (a.mean[i] - b.mean[i]) / se;
    EXPECT_LT(std::fabs(z), z_max) << what << ": block value " << i << ": " << a.mean[i] << " vs "
                                   << b.mean[i] << " (se " << se << ")";
    ++compared;
  }
  return compared;
}

/// Per-pixel means (RGB, row-major) of a render of `spp` samples per pixel.
inline std::vector<float> pixel_means(const TileResult& r, uint32_t spp) {
  std::vector<float> out(r.sum.size());
  for (size_t i = 0; i < out.size(); ++i) out[i] = float(from_fixed(r.sum[i]) / spp);
  return out;
}

/// Paired comparison of two renders of the same image (pixel means `a` and `b`, `width` wide)
/// whose pixels are independent of each other, whatever the sampler within a pixel: per pixel
/// D = a - b has mean 0 if both estimate the same image. Per `block` x `block` block and
/// channel, the mean of D over its standard error (from the D's own spread) is held below
/// `z_max`; blocks whose D all agree must have mean 0. Returns the number of comparisons made.
/// blocks_compared() counts them beforehand, for the Bonferroni bound of a family of calls.
inline size_t expect_same_expectation(const std::vector<float>& a, const std::vector<float>& b,
                                      uint32_t width, uint32_t height, uint32_t block, double z_max,
                                      const std::string& what) {
  EXPECT_EQ(a.size(), b.size()) << what;
  if (a.size() != b.size() || a.size() != size_t{width} * height * 3) {
    ADD_FAILURE() << what << ": " << a.size() << " values, not " << width << " x " << height
                  << " x 3";
    return 0;
  }
  size_t compared = 0;
  for (uint32_t by = 0; by + block <= height; by += block) {
    for (uint32_t bx = 0; bx + block <= width; bx += block) {
      for (int ch = 0; ch < 3; ++ch) {
        double s = 0.0, s2 = 0.0;
        for (uint32_t y = by; y < by + block; ++y) {
          for (uint32_t x = bx; x < bx + block; ++x) {
            const size_t i = (size_t{y} * width + x) * 3 + ch;
            const double d = double(a[i]) - double(b[i]);
            s += d;
            s2 += d * d;
          }
        }
        const double n = double(block) * block, mean = s / n;
        const double se = std::sqrt(std::max(0.0, (s2 / n - mean * mean) / (n - 1.0)));
        ++compared;
        if (se == 0.0) {
          EXPECT_EQ(mean, 0.0) << what << ": block " << bx << "," << by;
          continue;
        }
        EXPECT_LT(std::fabs(mean / se), z_max)
            << what << ": block at " << bx << "," << by << " channel " << ch << ": mean difference "
            << mean << " (standard error " << se << ")";
      }
    }
  }
  return compared;
}

/// The comparisons expect_same_expectation() makes on an image of this size.
inline size_t blocks_compared(uint32_t width, uint32_t height, uint32_t block) {
  return size_t{width / block} * (height / block) * 3;
}

/// True when every sum of `r` is a finite number and no sample was dropped.
inline bool all_finite(const TileResult& r) {
  for (size_t i = 0; i < r.sum.size(); ++i) {
    if (!std::isfinite(from_fixed(r.sum[i])) || !std::isfinite(from_fixed(r.sum_sq[i])))
      return false;
  }
  return r.nonfinite == 0;
}

}  // namespace rayfarm::testing
