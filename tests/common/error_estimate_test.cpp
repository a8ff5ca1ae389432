// The error estimate from a film's own samples. The variance comes from exact fixed-point sums; it
// is checked against a two-pass computation in long double, on a stiff case where the naive
// one-pass formula in double loses digits, and for independence from the order of merging.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>

#include "common/image/error_estimate.h"

namespace rayfarm {
namespace {

/// A one-pixel result holding `samples` (each channel the same value).
TileResult one_pixel(const std::vector<double>& samples, uint32_t first_sample = 0) {
  TileResult r({0, 0, 1, 1}, {first_sample, first_sample + uint32_t(samples.size())});
  for (double x : samples) {
    for (int c = 0; c < 3; ++c) {
      r.sum[c] += to_fixed(x);
      r.sum_sq[c] += to_fixed(x * x);
    }
  }
  return r;
}

/// Two-pass variance of the mean, in long double.
double two_pass_variance_of_mean(const std::vector<double>& x) {
  long double mean = 0;
  for (double v : x) mean += v;
  mean /= x.size();
  long double ss = 0;
  for (double v : x) ss += (v - mean) * (v - mean);
  return static_cast<double>(ss / (x.size() - 1) / x.size());
}

TEST(VarianceOfMean, AgreesWithATwoPassComputation) {
  std::mt19937_64 rng(7);
  std::exponential_distribution<double> heavy(0.5);  // skewed, like path-traced samples
  for (int n : {2, 3, 17, 1000}) {
    std::vector<double> x(n);
    // Values on the fixed-point grid, so that the only difference is the arithmetic.
    for (double& v : x) v = std::ldexp(std::round(std::ldexp(heavy(rng), 20)), -20);
    const TileResult r = one_pixel(x);
    const double expected = two_pass_variance_of_mean(x);
    EXPECT_NEAR(variance_of_mean(r.sum[0], r.sum_sq[0], n), expected, 1e-12 * expected) << n;
  }
}

TEST(VarianceOfMean, StiffCaseKeepsItsDigits) {
  // Mean 1e6, spread 1: the one-pass formula sum_sq - sum^2/n in double cancels 12 of its 16
  // digits. Samples alternate 1e6 - 1 and 1e6 + 1: sample variance n/(n-1), variance of the
  // mean 1/(n-1).
  const int n = 100000;
  std::vector<double> x(n);
  for (int i = 0; i < n; ++i) x[i] = 1e6 + (i % 2 ? 1.0 : -1.0);
  const TileResult r = one_pixel(x);
  const double exact = 1.0 / (n - 1);
  EXPECT_NEAR(variance_of_mean(r.sum[0], r.sum_sq[0], n), exact, 1e-9 * exact);

  double sum = 0, sum_sq = 0;
  for (double v : x) sum += v, sum_sq += v * v;
  const double naive = (sum_sq - sum * sum / n) / (double(n) * (n - 1));
  EXPECT_GT(std::fabs(naive - exact), 1e-6 * exact)
      << "the stiff case no longer shows the cancellation it is meant to guard against";
}

TEST(VarianceOfMean, ConstantSamplesHaveNoVarianceAndOneSampleIsUnknown) {
  const TileResult r = one_pixel(std::vector<double>(1000, 0.7));
  EXPECT_LT(variance_of_mean(r.sum[0], r.sum_sq[0], 1000), 1e-15);
  EXPECT_EQ(variance_of_mean(r.sum[0], r.sum_sq[0], 1), INFINITY);
  EXPECT_EQ(variance_of_mean(r.sum[0], r.sum_sq[0], 0), INFINITY);
}

TEST(ErrorEstimate, DoesNotDependOnHowSamplesArePassedOrMerged) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 3.0);
  std::vector<double> x(64);
  for (double& v : x) v = u(rng);
  Film whole(1, 1), passes(1, 1);
  whole.add(one_pixel(x));
  // Four passes of 16, merged in a scrambled order.
  for (uint32_t p : {2u, 0u, 3u, 1u}) {
    passes.add(one_pixel(std::vector<double>(x.begin() + p * 16, x.begin() + p * 16 + 16), p * 16));
  }
  const ErrorEstimate a = estimate_error(whole), b = estimate_error(passes);
  EXPECT_EQ(a.rel_mse, b.rel_mse);
  EXPECT_EQ(a.mse, b.mse);
  EXPECT_TRUE(a.known);
  // By hand: every channel has the same variance v and mean m.
  const double v = two_pass_variance_of_mean(x);
  double m = 0;
  for (double s : x) m += s;
  m /= x.size();
  EXPECT_NEAR(a.mse, v, 1e-9 * v);
  EXPECT_NEAR(a.rel_mse, v / (m * m + kRelMseEpsilon), 1e-9 * a.rel_mse);
  EXPECT_NEAR(a.rmse(), std::sqrt(v), 1e-9);
}

TEST(ErrorEstimate, AFireflyIsJudgedAgainstItsNeighboursNotItself) {
  // A 3x3 film of constant 0.5 samples, except the centre: one sample of 1000 among 16.
  Film film(3, 3);
  for (uint32_t y = 0; y < 3; ++y) {
    for (uint32_t x = 0; x < 3; ++x) {
      std::vector<double> samples(16, 0.5);
      if (x == 1 && y == 1) samples[7] = 1000.0;
      TileResult r = one_pixel(samples);
      r.rect = {x, y, x + 1, y + 1};
      film.add(r);
    }
  }
  std::vector<double> centre(16, 0.5);
  centre[7] = 1000.0;
  const double var = two_pass_variance_of_mean(centre);
  // Only the centre varies; its value is judged as the neighbours' 0.5, not its mean of ~63.
  const double expected = var / (0.25 + kRelMseEpsilon) / 9.0;
  EXPECT_NEAR(estimate_error(film).rel_mse, expected, 1e-9 * expected);
  double mean = 0;
  for (double v : centre) mean += v / 16;
  EXPECT_GT(estimate_error(film).rel_mse, 100 * var / (mean * mean + kRelMseEpsilon) / 9.0)
      << "dividing by the firefly's own mean would understate its error";
  // A tile's estimate reads only its own pixels: the centre alone is judged by itself.
  EXPECT_NEAR(estimate_error(film, {1, 1, 2, 2}).rel_mse, var / (mean * mean + kRelMseEpsilon),
              1e-9 * var);
}

TEST(ErrorEstimate, UnknownWhileAPixelHasFewerThanTwoSamples) {
  Film film(2, 1);
  TileResult left({0, 0, 1, 1}, {0, 4});
  left.sum_sq[0] = to_fixed(1.0);
  film.add(left);
  const ErrorEstimate e = estimate_error(film);
  EXPECT_FALSE(e.known);
  EXPECT_EQ(e.rel_mse, INFINITY);
  // The left pixel alone is known.
  EXPECT_TRUE(estimate_error(film, {0, 0, 1, 1}).known);
  EXPECT_EQ(variance_rgb(film)[3], INFINITY);
}

/// The estimate as its definition reads, pixel by pixel with nth_element: what the fast one in
/// error_estimate.cpp (means converted once, a median network) must reproduce.
std::pair<double, double> plain_rel_mse_and_mse(const Film& film, const TileRect& rect) {
  const auto mean = [&](uint32_t x, uint32_t y, int c) {
    const size_t p = size_t{y} * film.width() + x;
    return from_fixed(film.sum()[p * 3 + c]) / film.spp()[p];
  };
  long double rel = 0, mse = 0;
  for (uint32_t y = rect.y0; y < rect.y1; ++y) {
    for (uint32_t x = rect.x0; x < rect.x1; ++x) {
      const size_t p = size_t{y} * film.width() + x;
      for (int c = 0; c < 3; ++c) {
        std::vector<double> v;
        for (uint32_t yy = y > rect.y0 ? y - 1 : y; yy <= std::min(y + 1, rect.y1 - 1); ++yy)
          for (uint32_t xx = x > rect.x0 ? x - 1 : x; xx <= std::min(x + 1, rect.x1 - 1); ++xx)
            v.push_back(mean(xx, yy, c));
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        const double var =
            variance_of_mean(film.sum()[p * 3 + c], film.sum_sq()[p * 3 + c], film.spp()[p]);
        const double value = std::max(v[v.size() / 2], mean(x, y, c) - 2.0 * std::sqrt(var));
        rel += var / (value * value + kRelMseEpsilon);
        mse += var;
      }
    }
  }
  const long double values = 3.0L * rect.pixel_count();
  return {static_cast<double>(rel / values), static_cast<double>(mse / values)};
}

TEST(ErrorEstimate, EqualsItsDefinitionBitForBitOnRandomFilms) {
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> level(0, 5);  // few levels: ties in the medians
  std::exponential_distribution<double> heavy(1.0);
  std::uniform_int_distribution<uint32_t> count(2, 9);
  // Small films (every pixel on a border) and wider ones whose inner pixels take the median
  // network several at a time; pixels with different sample counts, and huge sums (beyond 64
  // bits of fixed point) in some.
  for (int trial = 0; trial < 40; ++trial) {
    const uint32_t w = trial < 20 ? 1 + trial % 7 : 3 + (trial * 7) % 37;
    const uint32_t h = trial < 20 ? 1 + (trial * 3) % 5 : 3 + trial % 6;
    Film film(w, h);
    for (uint32_t y = 0; y < h; ++y) {
      for (uint32_t x = 0; x < w; ++x) {
        const uint32_t n = trial % 3 == 0 ? count(rng) : 8;
        const double scale = trial % 5 == 4 && (x + y) % 4 == 0 ? 1e9 : 1.0;
        TileResult r({x, y, x + 1, y + 1}, {0, n});
        for (size_t i = 0; i < r.sum.size(); ++i) {
          for (uint32_t s = 0; s < n; ++s) {
            const double v = scale * (trial % 2 ? level(rng) * 0.25 : heavy(rng));
            r.sum[i] += to_fixed(v);
            r.sum_sq[i] += to_fixed(v * v);
          }
        }
        film.add(r);
      }
    }
    for (const TileRect& rect :
         {TileRect{0, 0, w, h}, TileRect{0, 0, (w + 1) / 2, h}, TileRect{w / 2, h / 2, w, h}}) {
      const ErrorEstimate e = estimate_error(film, rect);
      const auto [rel, mse] = plain_rel_mse_and_mse(film, rect);
      EXPECT_EQ(e.rel_mse, rel) << "film " << w << "x" << h << ", trial " << trial;
      EXPECT_EQ(e.mse, mse) << "film " << w << "x" << h << ", trial " << trial;
    }
  }
}

TEST(TiledErrorEstimate, TheWholeIsThePixelWeightedMeanOfTheTilesAndFollowsUpdates) {
  std::mt19937_64 rng(5);
  std::exponential_distribution<double> heavy(1.0);
  const auto noisy = [&](TileRect rect, uint32_t first, uint32_t count, double scale) {
    TileResult r(rect, {first, first + count});
    for (size_t i = 0; i < r.sum.size(); ++i) {
      for (uint32_t s = 0; s < count; ++s) {
        const double x = scale * heavy(rng);
        r.sum[i] += to_fixed(x);
        r.sum_sq[i] += to_fixed(x * x);
      }
    }
    return r;
  };
  const FilmSize size{10, 7};
  Film film(size.width, size.height);
  TiledErrorEstimate tiled(split_tiles(size, 4));  // 3 x 2 tiles of 4x4, 2x4, 4x3, 2x3 pixels
  ASSERT_EQ(tiled.tiles().size(), 6u);
  EXPECT_FALSE(tiled.whole().known);
  EXPECT_EQ(tiled.worst_tile(), 0) << "a tile not known yet is the worst: its error is unbounded";
  EXPECT_EQ(TiledErrorEstimate({}).worst_tile(), -1);
  EXPECT_FALSE(TiledErrorEstimate({}).whole().known);

  for (const TileRect& rect : tiled.tiles()) film.add(noisy(rect, 0, 8, 1.0));
  tiled.update_all(film);
  long double rel = 0;
  for (uint32_t t = 0; t < tiled.tiles().size(); ++t) {
    const ErrorEstimate e = estimate_error(film, tiled.tiles()[t]);
    EXPECT_EQ(tiled.tile(t).rel_mse, e.rel_mse);
    rel += static_cast<long double>(e.rel_mse) * e.pixels;
  }
  const ErrorEstimate whole = tiled.whole();
  EXPECT_TRUE(whole.known);
  EXPECT_EQ(whole.pixels, 70u);
  EXPECT_DOUBLE_EQ(whole.rel_mse, static_cast<double>(rel / 70));
  // One tile much noisier: the worst once it is updated, and not before.
  film.add(noisy(tiled.tiles()[4], 8, 8, 50.0));
  const int before = tiled.worst_tile();
  tiled.update(film, 4);
  EXPECT_EQ(tiled.worst_tile(), 4) << "was " << before;
  EXPECT_GT(tiled.whole().rel_mse, whole.rel_mse);
  // One tile covering the film: the same figure as estimate_error of the film.
  TiledErrorEstimate one(split_tiles(size, 16));
  one.update_all(film);
  EXPECT_EQ(one.whole().rel_mse, estimate_error(film).rel_mse);
}

}  // namespace
}  // namespace rayfarm
