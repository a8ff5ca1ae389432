// The path sampler: Sobol' points that keep their stratification under shuffling and Owen
// scrambling, a sample's numbers that depend on (seed, pixel, sample index) alone, and the
// independent sampler that reads the hashed stream in the order the path asks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include "renderer/samplers/path_sampler.h"
#include "renderer/samplers/sobol.h"

namespace rayfarm {
namespace {

TEST(Sobol, ReverseBitsAndOwenScrambleArePermutations) {
  EXPECT_EQ(sobol::reverse_bits(1u), 0x80000000u);
  EXPECT_EQ(sobol::reverse_bits(0x0000ff01u), 0x80ff0000u);
  // A nested scramble maps the 2^m fractions k / 2^m (top m bits) onto the same set: the top m
  // bits of the output depend on the top m bits of the input only.
  for (uint32_t key : {0u, 1u, 0xdeadbeefu}) {
    std::set<uint32_t> tops;
    for (uint32_t k = 0; k < 256; ++k) {
      const uint32_t x = (k << 24) | (k * 2654435761u >> 8);  // arbitrary low bits
      const uint32_t y = sobol::owen_scramble(x, key);
      EXPECT_EQ(y >> 24, sobol::owen_scramble(k << 24, key) >> 24);
      tops.insert(y >> 24);
    }
    EXPECT_EQ(tops.size(), 256u) << "key " << key;
  }
}

TEST(Sobol, ReversedTablesAreTheGeneratorMatrices) {
  // The lookup tables agree with the bit-by-bit product for indices with random high bits.
  uint32_t x = 12345u;
  for (int i = 0; i < 10000; ++i) {
    x = x * 1664525u + 1013904223u;
    for (int d = 0; d < 4; ++d) {
      ASSERT_EQ(sobol::sobol_reversed(sobol::reverse_bits(x), d),
                sobol::reverse_bits(sobol::sobol_bits(x, d)))
          << "index " << x << ", dimension " << d;
    }
  }
}

TEST(Sobol, LanesComputeTheScalarDefinition) {
  // sample_bits() works on four coordinates at once; each must be the definition written with
  // the scalar pieces: the index shuffled by an Owen scramble under the key's low half, then
  // Sobol' coordinate d of it Owen-scrambled under the high half plus d golden-ratio steps.
  // sample_bits() runs the SSE4.1 code where the CPU has it; both that code and the portable
  // one are checked directly too.
#ifdef RAYFARM_SOBOL_SSE41
  EXPECT_EQ(sobol::kHasSse41, __builtin_cpu_supports("sse4.1") != 0);
#endif
  uint64_t key = 0x0123456789abcdefull;
  uint32_t index = 0;
  for (int i = 0; i < 20000; ++i) {
    key = mix64(key + uint64_t(i));
    // Small indices (the usual case) and indices with random high bits.
    index = i % 2 == 0 ? uint32_t(i) : static_cast<uint32_t>(key >> 17);
    const auto shuffle_key = static_cast<uint32_t>(key), scramble_key = uint32_t(key >> 32);
    const uint32_t shuffled = sobol::owen_scramble(index, shuffle_key);
    const std::array<uint32_t, 4> bits = sobol::sample_bits<4>(index, key);
    const std::array<float, 4> floats = sobol::sample<4>(index, key);
    const std::array<uint32_t, 3> three = sobol::sample_bits<3>(index, key);
    const sobol::Lanes portable = sobol::sample_lanes_portable(sobol::reverse_bits(index), key);
#ifdef RAYFARM_SOBOL_SSE41
    // The SSE4.1 code itself, not only through the CPU check, where this CPU runs it.
    const sobol::Lanes sse41 = sobol::kHasSse41
                                   ? sobol::sample_lanes_sse41(sobol::reverse_bits(index), key)
                                   : portable;
#endif
    for (int d = 0; d < 4; ++d) {
      const uint32_t want = sobol::owen_scramble(sobol::sobol_bits(shuffled, d),
                                                 scramble_key + 0x9e3779b9u * uint32_t(d));
      ASSERT_EQ(bits[d], want) << "index " << index << ", key " << key << ", dimension " << d;
      ASSERT_EQ(portable[d], want) << "portable code, index " << index << ", dimension " << d;
#ifdef RAYFARM_SOBOL_SSE41
      ASSERT_EQ(sse41[d], want) << "SSE4.1 code, index " << index << ", dimension " << d;
#endif
      ASSERT_EQ(floats[d], sobol::to_unit_float(want)) << "index " << index << ", dimension " << d;
      if (d < 3) {
        ASSERT_EQ(three[d], want);
      }
    }
    ASSERT_EQ(sobol::sample_bits_reversed<4>(sobol::reverse_bits(index), key), bits);
  }
}

TEST(Sobol, FirstDimensionsAreTheKnownSequence) {
  // Dimension 0 is van der Corput; dimension 1 the standard second Sobol' dimension (direction
  // numbers 1/2, 3/4, 5/8, in index order, not Gray-code order).
  const float d0[] = {0.f, 0.5f, 0.25f, 0.75f, 0.125f, 0.625f, 0.375f, 0.875f};
  const float d1[] = {0.f, 0.5f, 0.75f, 0.25f, 0.625f, 0.125f, 0.375f, 0.875f};
  for (uint32_t i = 0; i < 8; ++i) {
    EXPECT_EQ(sobol::to_unit_float(sobol::sobol_bits(i, 0)), d0[i]) << i;
    EXPECT_EQ(sobol::to_unit_float(sobol::sobol_bits(i, 1)), d1[i]) << i;
  }
}

// Whether the 2^m points of `pts` put one in each elementary interval of size 2^-a x 2^-(m-a)
// for every a: a (0, m, 2)-net in base 2.
bool is_net(const std::vector<std::array<float, 2>>& pts, int m) {
  for (int a = 0; a <= m; ++a) {
    std::vector<int> count(size_t{1} << m, 0);
    for (const auto& p : pts) {
      const auto ix = static_cast<uint32_t>(p[0] * float(1u << a));
      const auto iy = static_cast<uint32_t>(p[1] * float(1u << (m - a)));
      ++count[(size_t{ix} << (m - a)) | iy];
    }
    if (std::any_of(count.begin(), count.end(), [](int c) { return c != 1; })) return false;
  }
  return true;
}

TEST(Sobol, ScrambledPrefixesStayStratified) {
  // For every key and every power of two 2^m up to 2^12, the first 2^m points: each coordinate
  // has one point per interval of width 2^-m, and the first two coordinates form a (0, m, 2)-net.
  for (uint64_t key : {mix64(0), mix64(42), mix64(0x9e3779b97f4a7c15)}) {
    for (int m = 0; m <= 12; ++m) {
      const uint32_t n = 1u << m;
      std::vector<std::array<float, 2>> pair;
      std::vector<std::vector<uint32_t>> strata(4, std::vector<uint32_t>(n, 0));
      for (uint32_t i = 0; i < n; ++i) {
        const std::array<float, 4> p = sobol::sample<4>(i, key);
        for (int d = 0; d < 4; ++d) {
          ASSERT_GE(p[d], 0.f);
          ASSERT_LT(p[d], 1.f);
          ++strata[d][static_cast<uint32_t>(p[d] * float(n))];
        }
        pair.push_back({p[0], p[1]});
      }
      for (int d = 0; d < 4; ++d) {
        EXPECT_TRUE(
            std::all_of(strata[d].begin(), strata[d].end(), [](uint32_t c) { return c == 1; }))
            << "key " << key << ", 2^" << m << " points, dimension " << d;
      }
      EXPECT_TRUE(is_net(pair, m)) << "key " << key << ", 2^" << m << " points";
    }
  }
}

TEST(Sobol, KeysDecorrelateAndUnscrambledIsNotUsed) {
  // Different keys give different points, and no key gives the unscrambled sequence (the origin
  // as its first point would be a fixed pattern in every pixel).
  std::set<float> firsts;
  for (uint64_t key = 0; key < 64; ++key) firsts.insert(sobol::sample<1>(0, mix64(key))[0]);
  EXPECT_GT(firsts.size(), 60u);
  EXPECT_EQ(firsts.count(0.f), 0u);
}

TEST(Sobol, ScrambledPointsAreUniformOnAverage) {
  // Over 4096 keys, point 5's coordinates are uniform: mean 1/2 (standard error
  // sqrt(1/12 / 4096) = 0.0045) and the pair's product has mean 1/4 (independent coordinates;
  // standard error about sqrt(7/144 / 4096) = 0.0034). 5 standard errors over 6 checks: a false
  // alarm has probability below 5e-6.
  const int keys = 4096;
  std::array<double, 4> mean{};
  double prod01 = 0.0, prod23 = 0.0;
  for (int k = 0; k < keys; ++k) {
    const std::array<float, 4> p = sobol::sample<4>(5, mix64(uint64_t(k)));
    for (int d = 0; d < 4; ++d) mean[d] += p[d] / keys;
    prod01 += double(p[0]) * p[1] / keys;
    prod23 += double(p[2]) * p[3] / keys;
  }
  const double se = std::sqrt(1.0 / 12.0 / keys), se_prod = std::sqrt(7.0 / 144.0 / keys);
  for (int d = 0; d < 4; ++d) EXPECT_NEAR(mean[d], 0.5, 5 * se) << "dimension " << d;
  EXPECT_NEAR(prod01, 0.25, 5 * se_prod);
  EXPECT_NEAR(prod23, 0.25, 5 * se_prod);
}

TEST(PathSampler, NumbersDependOnSeedPixelAndSampleOnly) {
  for (SamplerType type : {SamplerType::kSobol, SamplerType::kIndependent}) {
    PathSampler a(type, 7, 1234, 99), b(type, 7, 1234, 99);
    EXPECT_EQ(a.camera(), b.camera());
    for (uint32_t depth : {0u, 1u, 63u, 64u, 200u}) {
      EXPECT_EQ(a.light(depth), b.light(depth)) << sampler_name(type);
      EXPECT_EQ(a.scatter(depth), b.scatter(depth)) << sampler_name(type);
      EXPECT_EQ(a.roulette(), b.roulette()) << sampler_name(type);
    }
    EXPECT_NE(PathSampler(type, 7, 1234, 99).camera(), PathSampler(type, 8, 1234, 99).camera());
    EXPECT_NE(PathSampler(type, 7, 1234, 99).camera(), PathSampler(type, 7, 1235, 99).camera());
    EXPECT_NE(PathSampler(type, 7, 1234, 99).camera(), PathSampler(type, 7, 1234, 98).camera());
  }
}

TEST(PathSampler, IndependentReadsTheSampleStreamInOrder) {
  PathSampler s(SamplerType::kIndependent, 3, 17, 5);
  Pcg32 rng = sample_stream(3, 17, 5);
  for (float v : s.camera()) EXPECT_EQ(v, rng.next_float());
  for (float v : s.light(0)) EXPECT_EQ(v, rng.next_float());
  for (float v : s.scatter(0)) EXPECT_EQ(v, rng.next_float());
  EXPECT_EQ(s.roulette(), rng.next_float());
}

TEST(PathSampler, SobolPixelOffsetsStratifyEachPixel) {
  // The first 16 samples of a pixel put one camera offset in each of a 4 x 4 grid of cells.
  for (uint64_t pixel : {0u, 1u, 4095u}) {
    std::set<int> cells;
    for (uint32_t s = 0; s < 16; ++s) {
      const std::array<float, 4> u = PathSampler(SamplerType::kSobol, 1, pixel, s).camera();
      cells.insert(int(u[0] * 4) * 4 + int(u[1] * 4));
    }
    EXPECT_EQ(cells.size(), 16u) << "pixel " << pixel;
  }
}

TEST(PathSampler, DeepVerticesFallBackToTheStream) {
  // Past kSobolVertices the numbers are the hashed stream's; the roulette number of a Sobol'
  // vertex is its group's fourth coordinate, not a stream draw.
  PathSampler s(SamplerType::kSobol, 3, 17, 5);
  Pcg32 rng = sample_stream(3, 17, 5);
  const std::array<float, 3> deep = s.scatter(PathSampler::kSobolVertices);
  for (float v : deep) EXPECT_EQ(v, rng.next_float());
  EXPECT_EQ(s.roulette(), rng.next_float());
  const std::array<float, 3> shallow = s.scatter(0);
  const float r = s.roulette();
  EXPECT_GE(r, 0.f);
  EXPECT_LT(r, 1.f);
  EXPECT_NE(shallow, deep);
  // The shallow vertex took nothing from the stream: the next deep draw is its next number.
  EXPECT_EQ(s.light(PathSampler::kSobolVertices)[0], rng.next_float());
}

TEST(PathSampler, UnreadLightNumbersLeaveTheOthersAlone) {
  // A vertex whose light reads no numbers: the Sobol' sampler leaves its group out, the stream
  // still draws it, and every other number of the path stays the same either way.
  for (SamplerType type : {SamplerType::kSobol, SamplerType::kIndependent}) {
    PathSampler read(type, 9, 4321, 77), unread(type, 9, 4321, 77);
    EXPECT_EQ(read.camera(), unread.camera());
    for (uint32_t depth : {0u, 1u, 2u, PathSampler::kSobolVertices - 1,
                           PathSampler::kSobolVertices, PathSampler::kSobolVertices + 1}) {
      const std::array<uint32_t, 3> all = read.light_bits(depth, true);
      const std::array<uint32_t, 3> some = unread.light_bits(depth, false);
      if (type == SamplerType::kSobol && depth < PathSampler::kSobolVertices) {
        EXPECT_EQ(some, (std::array<uint32_t, 3>{}));
      } else {
        EXPECT_EQ(some, all);  // drawn from the stream, in order
      }
      EXPECT_EQ(read.scatter(depth), unread.scatter(depth)) << "depth " << depth;
      EXPECT_EQ(read.roulette(), unread.roulette()) << "depth " << depth;
    }
  }
}

}  // namespace
}  // namespace rayfarm
