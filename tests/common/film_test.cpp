// The fixed-point accumulator and the film: exactness, order independence, and the splitting of
// an image into units of work.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/image/film.h"
#include "common/image/fixed.h"
#include "tests/support/tile_result_compare.h"

namespace rayfarm {
namespace {

constexpr double kResolution = 1.0 / 1099511627776.0;  // 2^-40

/// A random float with exponent in [min_exp, max_exp], random 23-bit mantissa and sign.
float random_float(std::mt19937_64& rng, int min_exp, int max_exp) {
  std::uniform_int_distribution<int> exponent(min_exp, max_exp);
  const auto mantissa = static_cast<float>(rng() & 0x7fffff);
  const float magnitude = std::ldexp(1.f + mantissa / 8388608.f, exponent(rng));
  return (rng() & 1) ? -magnitude : magnitude;
}

TEST(FixedTest, ExactForEveryFloatOfMagnitudeAtLeastTwoToMinus16) {
  std::mt19937_64 rng(1);
  // Up to 2^46: beyond the int64 fast path of to_fixed (2^23) and near its 2^87 limit.
  std::vector<float> values = {0.f, 1.f, -1.f, 0x1p-16f, -0x1p-16f, 0x1.fffffep-16f};
  values.insert(values.end(), {0x1p23f, 0x1.fffffep22f, 0x1.fffffep46f, float(kMaxSampleValue)});
  for (int i = 0; i < 200000; ++i) values.push_back(random_float(rng, -16, 46));
  for (float f : values) {
    const double back = from_fixed(to_fixed(f));
    ASSERT_EQ(back, double(f)) << std::hexfloat << f;
  }
}

TEST(FixedTest, TruncatesSmallerValuesTowardZeroBelowResolution) {
  std::mt19937_64 rng(2);
  std::vector<float> values = {0x1p-17f, 0x1.fffffep-17f, 0x1p-40f, 0x1p-41f, 1e-30f};
  values.push_back(std::numeric_limits<float>::denorm_min());
  for (int i = 0; i < 200000; ++i) values.push_back(random_float(rng, -149, -17));
  bool some_inexact = false;
  for (float f : values) {
    const double back = from_fixed(to_fixed(f));
    ASSERT_LT(std::fabs(back - double(f)), kResolution) << std::hexfloat << f;
    ASSERT_LE(std::fabs(back), std::fabs(double(f))) << std::hexfloat << f;  // toward zero
    ASSERT_GE(back * f, 0.0) << std::hexfloat << f;                          // same sign or 0
    some_inexact |= back != double(f);
  }
  EXPECT_TRUE(some_inexact);
  EXPECT_EQ(from_fixed(to_fixed(0x1p-41f)), 0.0);
}

TEST(FixedTest, FastConversionsRoundAsThePlainOnes) {
  // Values that fit 64 bits take one instruction; the result must be the 128-bit conversion's,
  // bit for bit, at the edges (ties of double's 53 bits, the int64 limits) and beyond 64 bits.
  const Fixed two64 = Fixed{1} << 64;
  const std::vector<Fixed> values = {0,
                                     1,
                                     -1,
                                     (Fixed{1} << 53) + 1,
                                     (Fixed{1} << 53) + 3,
                                     -((Fixed{1} << 53) + 1),
                                     (Fixed{1} << 62) + 511,
                                     (Fixed{1} << 62) + 513,
                                     INT64_MAX,
                                     INT64_MIN,
                                     Fixed{INT64_MAX} + 1,
                                     Fixed{INT64_MIN} - 1,
                                     two64 + 12345,
                                     -two64 * 1000 - 7};
  for (const Fixed v : values) {
    SCOPED_TRACE(static_cast<double>(v));
    const double plain = static_cast<double>(v) * (1.0 / 1099511627776.0);
    EXPECT_EQ(from_fixed(v), plain);
    EXPECT_EQ(fixed_raw_long_double(v), static_cast<long double>(v));
  }
}

TEST(FixedTest, PartsRoundTripIncludingNegativeValues) {
  const Fixed minus_one = to_fixed(-1.0);
  EXPECT_EQ(fixed_hi(minus_one), -1);
  EXPECT_EQ(fixed_lo(minus_one), ~uint64_t{0} - ((uint64_t{1} << 40) - 1));  // 2^64 - 2^40
  EXPECT_TRUE(fixed_from_parts(fixed_lo(minus_one), fixed_hi(minus_one)) == minus_one);

  std::mt19937_64 rng(3);
  std::vector<Fixed> values = {0, 1, -1, to_fixed(kMaxSampleValue), -to_fixed(kMaxSampleValue)};
  for (int i = 0; i < 10000; ++i) {
    values.push_back(fixed_from_parts(rng(), static_cast<int64_t>(rng())));
    values.push_back(to_fixed(random_float(rng, -30, 46)));
  }
  for (Fixed v : values) {
    ASSERT_TRUE(fixed_from_parts(fixed_lo(v), fixed_hi(v)) == v);
    ASSERT_EQ(fixed_hi(v) < 0, v < 0);
  }
}

/// Radiance samples of a small image, indexed [pixel][sample][channel], over a wide range.
struct Samples {
  uint32_t width, height, spp;
  std::vector<float> values;
  float at(uint32_t x, uint32_t y, uint32_t s, int c) const {
    return values[((size_t{y} * width + x) * spp + s) * 3 + c];
  }
};

Samples make_samples(uint32_t width, uint32_t height, uint32_t spp) {
  Samples samples{width, height, spp, {}};
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> log2_value(-24.0, 20.0);
  samples.values.resize(size_t{width} * height * spp * 3);
  for (float& v : samples.values) {
    v = (rng() % 10 == 0) ? 0.f : static_cast<float>(std::exp2(log2_value(rng)));
  }
  return samples;
}

/// Renders every tile x pass unit of `samples`, then merges them into a film in a shuffled order.
Film render_and_merge(const Samples& samples, uint32_t tile_size, uint32_t pass_spp,
                      uint64_t order_seed) {
  std::vector<TileResult> results;
  for (const TileRect& tile : split_tiles({samples.width, samples.height}, tile_size)) {
    for (const SampleRange& pass : split_passes(samples.spp, pass_spp)) {
      TileResult r(tile, pass);
      for (uint32_t y = tile.y0; y < tile.y1; ++y) {
        for (uint32_t x = tile.x0; x < tile.x1; ++x) {
          const size_t i = (size_t{y - tile.y0} * tile.width() + (x - tile.x0)) * 3;
          for (uint32_t s = pass.begin; s < pass.end; ++s) {
            for (int c = 0; c < 3; ++c) {
              const double v = samples.at(x, y, s, c);
              r.sum[i + c] += to_fixed(v);
              r.sum_sq[i + c] += to_fixed(v * v);
            }
          }
        }
      }
      r.rays = 2 * size_t{tile.pixel_count()} * pass.count();
      results.push_back(std::move(r));
    }
  }
  std::mt19937_64 rng(order_seed);
  std::shuffle(results.begin(), results.end(), rng);
  Film film(samples.width, samples.height);
  for (const TileResult& r : results) film.add(r);
  return film;
}

std::vector<uint32_t> bits_of(const std::vector<float>& values) {
  std::vector<uint32_t> bits(values.size());
  std::memcpy(bits.data(), values.data(), values.size() * sizeof(float));
  return bits;
}

TEST(FilmTest, AnyGroupingAndOrderGivesTheSameBits) {
  const Samples samples = make_samples(7, 5, 37);
  const Film reference = render_and_merge(samples, 7, 37, 0);
  struct Grouping {
    uint32_t tile_size, pass_spp;
    uint64_t order_seed;
  };
  for (const Grouping g : {Grouping{3, 1, 1}, Grouping{4, 5, 2}, Grouping{2, 64, 3},
                           Grouping{1, 16, 4}, Grouping{8, 36, 5}, Grouping{7, 37, 6}}) {
    SCOPED_TRACE("tile " + std::to_string(g.tile_size) + ", pass " + std::to_string(g.pass_spp));
    const Film film = render_and_merge(samples, g.tile_size, g.pass_spp, g.order_seed);
    EXPECT_TRUE(film.sum() == reference.sum());
    EXPECT_TRUE(film.sum_sq() == reference.sum_sq());
    EXPECT_EQ(bits_of(film.mean_rgb()), bits_of(reference.mean_rgb()));
    EXPECT_EQ(film.min_spp(), 37u);
    EXPECT_EQ(film.rays(), reference.rays());
  }

  // The exact sums are also right: each mean agrees with a double-precision mean.
  const std::vector<float> mean = reference.mean_rgb();
  for (uint32_t y = 0; y < samples.height; ++y) {
    for (uint32_t x = 0; x < samples.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        double sum = 0.0;
        for (uint32_t s = 0; s < samples.spp; ++s) sum += samples.at(x, y, s, c);
        const double expected = sum / samples.spp;
        EXPECT_NEAR(mean[(size_t{y} * samples.width + x) * 3 + c], expected, expected * 1e-6);
      }
    }
  }
}

TEST(FilmTest, MillionPassesOfAConstantGiveItBack) {
  // Blue's fixed-point sum needs more than 64 bits.
  const float constant[3] = {0.1f, 3.7f, 1234.5678f};
  Film film(1, 1);
  constexpr uint32_t kPasses = 1000000;
  for (uint32_t s = 0; s < kPasses; ++s) {
    TileResult r({0, 0, 1, 1}, {s, s + 1});
    for (int c = 0; c < 3; ++c) r.sum[c] = to_fixed(constant[c]);
    film.add(r);
  }
  ASSERT_EQ(film.spp_at(0, 0), kPasses);
  const std::vector<float> mean = film.mean_rgb();
  for (int c = 0; c < 3; ++c) {
    const double estimate = from_fixed(film.sum()[c]) / film.spp_at(0, 0);
    EXPECT_LE(std::fabs(estimate - constant[c]), 1e-12 * constant[c]) << c;
    EXPECT_EQ(mean[c], constant[c]) << c;
  }
}

TEST(FilmTest, FitsRejectsResultsOutsideOrMisshapen) {
  const Film film(10, 8);
  EXPECT_TRUE(film.fits(TileResult({0, 0, 10, 8}, {0, 4})));
  EXPECT_TRUE(film.fits(TileResult({8, 6, 10, 8}, {3, 4})));
  EXPECT_FALSE(film.fits(TileResult({8, 6, 11, 8}, {0, 4})));  // past the right edge
  EXPECT_FALSE(film.fits(TileResult({0, 7, 1, 9}, {0, 4})));   // past the bottom edge
  EXPECT_FALSE(film.fits(TileResult({3, 3, 3, 5}, {0, 4})));   // empty rectangle
  TileResult inverted({4, 3, 5, 5}, {0, 4});
  inverted.rect = {5, 3, 4, 5};
  EXPECT_FALSE(film.fits(inverted));
  EXPECT_FALSE(film.fits(TileResult({0, 0, 2, 2}, {4, 4})));  // no samples
  EXPECT_FALSE(film.fits(TileResult()));

  TileResult short_sum({0, 0, 2, 2}, {0, 1});
  short_sum.sum.pop_back();
  EXPECT_FALSE(film.fits(short_sum));
  TileResult long_sum_sq({0, 0, 2, 2}, {0, 1});
  long_sum_sq.sum_sq.push_back(0);
  EXPECT_FALSE(film.fits(long_sum_sq));
}

// A result rendered into again (Renderer::render into a kept result) starts as a new one would:
// its own rect and samples, zeroed sums of its own size, no counts, whatever it held before.
TEST(FilmTest, ResetResultIsANewOneForItsUnit) {
  TileResult used({0, 0, 4, 3}, {0, 8});
  for (Fixed& v : used.sum) v = to_fixed(2.5);
  for (Fixed& v : used.sum_sq) v = to_fixed(6.25);
  used.nonfinite = 2;
  used.rays = 77;
  for (const TileRect rect : {TileRect{1, 1, 3, 2}, TileRect{0, 0, 5, 5}}) {
    used.reset(rect, {8, 12});
    testing::expect_same_result(used, TileResult(rect, {8, 12}));
    EXPECT_EQ(used.nonfinite, 0u);
    EXPECT_EQ(used.rays, 0u);
    EXPECT_TRUE(used.well_formed());
    for (Fixed& v : used.sum) v = to_fixed(1.0);  // dirty again for the next size
    used.rays = 5;
  }
}

TEST(FilmTest, AddCountsSamplesRaysAndDroppedSamples) {
  Film film(4, 2);
  EXPECT_EQ(film.min_spp(), 0u);
  TileResult left({0, 0, 2, 2}, {0, 8});
  left.nonfinite = 3;
  left.rays = 100;
  left.sum[0] = to_fixed(8.0);
  film.add(left);
  EXPECT_EQ(film.spp_at(1, 1), 8u);
  EXPECT_EQ(film.spp_at(2, 0), 0u);
  EXPECT_EQ(film.min_spp(), 0u);
  EXPECT_EQ(film.mean_rgb()[0], 1.f);
  EXPECT_EQ(film.mean_rgb()[2 * 3], 0.f);  // no sample yet

  TileResult right({2, 0, 4, 2}, {0, 4});
  right.rays = 50;
  film.add(right);
  EXPECT_EQ(film.min_spp(), 4u);
  EXPECT_EQ(film.nonfinite(), 3u);
  EXPECT_EQ(film.rays(), 150u);
}

TEST(SplitTest, TilesCoverTheImageExactlyOnce) {
  struct Case {
    uint32_t width, height, tile;
  };
  for (const Case k : {Case{100, 37, 16}, Case{64, 64, 16}, Case{1, 1, 8}, Case{17, 5, 1},
                       Case{5, 3, 100}, Case{33, 65, 32}}) {
    SCOPED_TRACE(std::to_string(k.width) + "x" + std::to_string(k.height) + " tile " +
                 std::to_string(k.tile));
    const std::vector<TileRect> tiles = split_tiles({k.width, k.height}, k.tile);
    const uint32_t columns = (k.width + k.tile - 1) / k.tile;
    const uint32_t rows = (k.height + k.tile - 1) / k.tile;
    EXPECT_EQ(tiles.size(), size_t{columns} * rows);
    std::vector<int> covered(size_t{k.width} * k.height, 0);
    for (const TileRect& t : tiles) {
      ASSERT_LT(t.x0, t.x1);
      ASSERT_LT(t.y0, t.y1);
      ASSERT_LE(t.x1, k.width);
      ASSERT_LE(t.y1, k.height);
      EXPECT_LE(t.width(), k.tile);
      EXPECT_LE(t.height(), k.tile);
      for (uint32_t y = t.y0; y < t.y1; ++y) {
        for (uint32_t x = t.x0; x < t.x1; ++x) ++covered[size_t{y} * k.width + x];
      }
    }
    EXPECT_TRUE(std::all_of(covered.begin(), covered.end(), [](int n) { return n == 1; }));
    // Row by row: sorted by (y0, x0).
    EXPECT_TRUE(
        std::is_sorted(tiles.begin(), tiles.end(), [](const TileRect& a, const TileRect& b) {
          return a.y0 != b.y0 ? a.y0 < b.y0 : a.x0 < b.x0;
        }));
  }
}

TEST(SplitTest, PassesCoverTheSampleRangeExactlyOnce) {
  for (uint32_t spp : {1u, 7u, 64u, 100u, 1000u}) {
    for (uint32_t pass : {1u, 3u, 64u, 128u, 1000u}) {
      SCOPED_TRACE("spp " + std::to_string(spp) + ", pass " + std::to_string(pass));
      const std::vector<SampleRange> passes = split_passes(spp, pass);
      ASSERT_FALSE(passes.empty());
      EXPECT_EQ(passes.front().begin, 0u);
      EXPECT_EQ(passes.back().end, spp);
      for (size_t i = 0; i < passes.size(); ++i) {
        EXPECT_GE(passes[i].count(), 1u);
        EXPECT_LE(passes[i].count(), pass);
        if (i + 1 < passes.size()) {
          EXPECT_EQ(passes[i].end, passes[i + 1].begin);
          EXPECT_EQ(passes[i].count(), pass);  // only the last may be shorter
        }
      }
    }
  }
  EXPECT_TRUE(split_passes(0, 4).empty());
}

bool is_power_of_two(uint32_t v) { return v != 0 && (v & (v - 1)) == 0; }

TEST(SplitTest, DefaultPassSppIsAPowerOfTwoWithinSpp) {
  for (uint32_t tile : {1u, 8u, 16u, 32u, 64u, 256u, 1000u}) {
    for (uint32_t spp : {1u, 2u, 64u, 1024u, 65536u, 1u << 20}) {
      const uint32_t pass = default_pass_spp(tile, spp);
      EXPECT_TRUE(is_power_of_two(pass)) << "tile " << tile << ", spp " << spp << ": " << pass;
      EXPECT_GE(pass, 1u);
      EXPECT_LE(pass, spp);
    }
  }
  // About 2^18 samples per unit, and at least 8 passes.
  EXPECT_EQ(default_pass_spp(16, 1u << 20), 1024u);
  EXPECT_EQ(default_pass_spp(64, 1u << 20), 64u);
  EXPECT_EQ(default_pass_spp(64, 256), 32u);
  EXPECT_EQ(default_pass_spp(64, 64), 8u);
  EXPECT_EQ(default_pass_spp(64, 12), 1u);
}

TEST(SplitTest, DefaultPassSppIsAPowerOfTwoForAnySpp) {
  for (uint32_t tile : {1u, 16u, 64u}) {
    for (uint32_t spp : {3u, 5u, 100u, 1000u, 3000u}) {
      const uint32_t pass = default_pass_spp(tile, spp);
      EXPECT_TRUE(is_power_of_two(pass)) << "tile " << tile << ", spp " << spp << ": " << pass;
      EXPECT_GE(pass, 1u);
      EXPECT_LE(pass, spp);
    }
  }
}

}  // namespace
}  // namespace rayfarm
