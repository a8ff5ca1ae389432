#pragma once
// Owen-scrambled Sobol' points in four dimensions, shuffled and scrambled per key: the
// low-discrepancy half of the path sampler (path_sampler.h).
//
// Only the first four Sobol' dimensions are used. Every group of up to four random numbers a
// path needs (the camera's, each bounce's light choice and point, each bounce's BSDF lobe,
// direction and roulette) reads those four dimensions with its own key: the sample index is
// first shuffled by a key-dependent nested permutation and each coordinate then
// Owen-scrambled under its own key. Within a group the points keep the Sobol' stratification
// (any power-of-two count of consecutive samples from 0 stratifies every coordinate and the first
// pair forms a (0, m, 2)-net); between groups the shuffles make them independent ("padding").
#include <array>
#include <cstdint>
#include <cstring>

namespace rayfarm::sobol {

/// reverse_bits() and lk_permute() on a 32-bit word or, the same operations in each lane, on a
/// vector of them (Lanes, below).
template <class Word>
constexpr Word reverse_word(Word x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
  x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
  return (x >> 16) | (x << 16);
}
template <class Word>
constexpr Word lk_permute_word(Word x, Word key) {
  x ^= x * 0x3d20adeau;
  x += key;
  x *= (key >> 16) | 1u;
  x ^= x * 0x05526c56u;
  x ^= x * 0x53a22864u;
  return x;
}

/// Reverses the 32 bits of x (bit 0 becomes bit 31).
constexpr uint32_t reverse_bits(uint32_t x) { return reverse_word(x); }

/// A random permutation of 32-bit words in which each output bit depends only on the input bit
/// at its place and those below it: x * even, x + c and x * odd carry information only upwards.
/// Applied to bit-reversed fractions it becomes a nested uniform (Owen) scramble: the first
/// digit of a fraction is flipped at random, each later digit by a choice that depends on the
/// digits before it. The multipliers are those published for this purpose (a hash-based
/// Laine-Karras permutation with good avalanche between bits).
constexpr uint32_t lk_permute(uint32_t x, uint32_t key) { return lk_permute_word(x, key); }

/// Nested uniform scramble of a fraction in [0, 1) written as 32 bits (bit 31 = 1/2).
constexpr uint32_t owen_scramble(uint32_t x, uint32_t key) {
  return reverse_bits(lk_permute(reverse_bits(x), key));
}

/// Generator matrices (as 32 direction numbers each, bit 31 = 1/2) of Sobol' dimensions 1-3
/// (dimension 0 is the van der Corput sequence: the index's bits reversed). Each comes from a
/// primitive polynomial x^s + a_1 x^{s-1} + ... + a_{s-1} x + 1 over GF(2) and s initial odd
/// numbers m_1..m_s (the standard choices): m_k = 2 a_1 m_{k-1} ^ 4 a_2 m_{k-2} ^ ...
/// ^ 2^s m_{k-s} ^ m_{k-s} for k > s, and direction number k is m_k / 2^k.
struct Polynomial {
  int degree;
  uint32_t inner;  ///< a_1 .. a_{s-1} as bits, a_1 the highest
  std::array<uint32_t, 3> m;
};

constexpr std::array<uint32_t, 32> direction_numbers(Polynomial p) {
  std::array<uint32_t, 33> m{};  // m[1..32]
  for (int k = 1; k <= p.degree; ++k) m[k] = p.m[k - 1];
  for (int k = p.degree + 1; k <= 32; ++k) {
    uint32_t v = m[k - p.degree] ^ (m[k - p.degree] << p.degree);
    for (int i = 1; i < p.degree; ++i) {
      if ((p.inner >> (p.degree - 1 - i)) & 1u) v ^= m[k - i] << i;
    }
    m[k] = v;
  }
  std::array<uint32_t, 32> v{};
  for (int k = 1; k <= 32; ++k) v[k - 1] = m[k] << (32 - k);
  return v;
}

inline constexpr std::array<std::array<uint32_t, 32>, 3> kDirections = {
    direction_numbers({1, 0, {1, 0, 0}}),  // x + 1
    direction_numbers({2, 1, {1, 3, 0}}),  // x^2 + x + 1
    direction_numbers({3, 1, {1, 3, 1}}),  // x^3 + x + 1
};

/// Coordinate `dim` (0-3) of Sobol' point `index`, unscrambled, as 32 bits (bit 31 = 1/2): what
/// the tables below are built from (and tests check them against); sample() reads the tables.
constexpr uint32_t sobol_bits(uint32_t index, int dim) {
  if (dim == 0) return reverse_bits(index);
  uint32_t x = 0;
  const std::array<uint32_t, 32>& v = kDirections[dim - 1];
  for (int bit = 0; index != 0; index >>= 1, ++bit) {
    if (index & 1u) x ^= v[bit];
  }
  return x;
}

/// The four generator matrices as lookup tables in the bit-reversed domain, which is where the
/// scrambles work: entry [dim][byte][b] is the bit-reversed XOR of the direction numbers that
/// index bits 31 - (8 byte + k) select, for the bits k set in b, so that for y = the reversed
/// index, reverse(sobol_bits(reverse(y), dim)) is four lookups on y's bytes. A shuffled index
/// has random high bits, and a loop over them costs a mispredicted branch per bit.
struct ReversedTables {
  std::array<std::array<std::array<uint32_t, 256>, 4>, 4> t{};
};

constexpr ReversedTables make_reversed_tables() {
  ReversedTables out;
  for (int d = 0; d < 4; ++d) {
    for (int byte = 0; byte < 4; ++byte) {
      for (uint32_t b = 0; b < 256; ++b) {
        uint32_t x = 0;
        for (int k = 0; k < 8; ++k) {
          if ((b >> k) & 1u) x ^= sobol_bits(1u << (31 - (8 * byte + k)), d);
        }
        out.t[d][byte][b] = reverse_bits(x);
      }
    }
  }
  return out;
}

inline constexpr ReversedTables kReversedTables = make_reversed_tables();

/// reverse_bits(sobol_bits(reverse_bits(y), dim)).
constexpr uint32_t sobol_reversed(uint32_t y, int dim) {
  const auto& t = kReversedTables.t[dim];
  return t[0][y & 0xffu] ^ t[1][(y >> 8) & 0xffu] ^ t[2][(y >> 16) & 0xffu] ^ t[3][y >> 24];
}

/// 32 scrambled bits to a float in [0, 1): the top 24 bits, so that rounding never gives 1.
constexpr float to_unit_float(uint32_t bits) { return static_cast<float>(bits >> 8) * 0x1p-24f; }

// The four coordinates of a point are computed side by side, one per lane of a 128-bit vector
// (GCC's and Clang's vector extensions: SSE2 on x86-64, or SSE4.1 where the CPU has it, see
// sample_lanes(); NEON on arm64). Each lane does exactly the scalar operations (reverse_word()
// and lk_permute_word() serve both), so the bits are those of reverse_bits(), lk_permute() and
// sobol_reversed() applied coordinate by coordinate (tests/renderer/sampler_test.cpp checks it).
using Lanes = uint32_t __attribute__((vector_size(16)));
using SignedLanes = int32_t __attribute__((vector_size(16)));
using FloatLanes = float __attribute__((vector_size(16)));

/// kReversedTables with the four dimensions side by side: entry [byte][b] holds
/// kReversedTables.t[d][byte][b] for d = 0..3, so that one 16-byte load serves all four.
struct LaneTables {
  std::array<std::array<std::array<uint32_t, 4>, 256>, 4> t{};
};

constexpr LaneTables make_lane_tables() {
  LaneTables out;
  for (int byte = 0; byte < 4; ++byte) {
    for (int b = 0; b < 256; ++b) {
      for (int d = 0; d < 4; ++d) out.t[byte][b][d] = kReversedTables.t[d][byte][b];
    }
  }
  return out;
}

alignas(16) inline constexpr LaneTables kLaneTables = make_lane_tables();

inline Lanes load_lanes(const std::array<uint32_t, 4>& entry) {
  Lanes v;
  std::memcpy(&v, entry.data(), sizeof v);
  return v;
}

/// sobol_reversed(y, d) for d = 0..3, one per lane.
inline Lanes sobol_reversed_lanes(uint32_t y) {
  const auto& t = kLaneTables.t;
  return load_lanes(t[0][y & 0xffu]) ^ load_lanes(t[1][(y >> 8) & 0xffu]) ^
         load_lanes(t[2][(y >> 16) & 0xffu]) ^ load_lanes(t[3][y >> 24]);
}

/// The four scrambled coordinates of point `index` of the sequence of `key` (a well-mixed 64-bit
/// hash), given reverse_bits(index), each with its bits still reversed: the index shuffled by a
/// nested permutation (which maps every aligned block of 2^m indices onto one such block, so the
/// first 2^m samples stay a net), then each Sobol' coordinate Owen-scrambled. A caller that
/// draws several groups for one sample reverses its index once.
inline Lanes sample_lanes_reversed(uint32_t reversed_index, uint64_t key) {
  // The shuffle and the scrambles both act on reversed bits; staying there between them leaves
  // one reversal per coordinate (owen_scramble(sobol_bits(owen_scramble(index)))).
  // `key` is already a hash: its low half keys the shuffle, its high half (offset per dimension
  // by the golden ratio) the coordinates' scrambles.
  const auto shuffle_key = static_cast<uint32_t>(key),
             scramble_key = static_cast<uint32_t>(key >> 32);
  const uint32_t y = lk_permute(reversed_index, shuffle_key);
  const Lanes keys = scramble_key + Lanes{0u, 0x9e3779b9u, 0x9e3779b9u * 2u, 0x9e3779b9u * 3u};
  return lk_permute_word(sobol_reversed_lanes(y), keys);
}

/// The four coordinates: sample_lanes_reversed() with each lane's bits put back in order.
inline Lanes sample_lanes_portable(uint32_t reversed_index, uint64_t key) {
  return reverse_word(sample_lanes_reversed(reversed_index, key));
}

#if defined(__x86_64__)
#define RAYFARM_SOBOL_SSE41 1
/// sample_lanes_portable() for CPUs with SSE4.1 (sobol.cpp): sample_lanes_reversed() compiled
/// for SSE4.1, whose pmulld multiplies four 32-bit lanes (the x86-64 baseline's SSE2 has no such
/// multiply, and GCC builds one from two pmuludq and shuffles: more instructions, and on the
/// AMD EPYC of docs/benchmarks.md about 50% more latency on a group, which the path loop waits
/// for), then each lane's bits reversed by SSSE3 byte shuffles in a third of reverse_word()'s
/// steps. Integer operations only: the bits are those of sample_lanes_portable().
Lanes sample_lanes_sse41(uint32_t reversed_index, uint64_t key);
/// Whether this CPU runs sample_lanes_sse41() (found once, at start-up).
extern const bool kHasSse41;
#endif

/// The four coordinates of sample_lanes_portable(), by the fastest code this CPU runs.
inline Lanes sample_lanes(uint32_t reversed_index, uint64_t key) {
#ifdef RAYFARM_SOBOL_SSE41
  if (kHasSse41) return sample_lanes_sse41(reversed_index, key);
#endif
  return sample_lanes_portable(reversed_index, key);
}

/// The first kDims coordinates of sample_lanes() as 32 bits each (bit 31 = 1/2).
template <int kDims = 4>
inline std::array<uint32_t, kDims> sample_bits_reversed(uint32_t reversed_index, uint64_t key) {
  static_assert(kDims >= 1 && kDims <= 4);
  const Lanes v = sample_lanes(reversed_index, key);
  std::array<uint32_t, kDims> out;
  for (int d = 0; d < kDims; ++d) out[d] = v[d];
  return out;
}

/// The first kDims coordinates of sample_lanes() as floats in [0, 1), to_unit_float() of each.
template <int kDims = 4>
inline std::array<float, kDims> sample_reversed(uint32_t reversed_index, uint64_t key) {
  static_assert(kDims >= 1 && kDims <= 4);
  // The top 24 bits are below 2^24: exact as signed integers and as floats.
  const FloatLanes f =
      __builtin_convertvector(reinterpret_cast<SignedLanes>(sample_lanes(reversed_index, key) >> 8),
                              FloatLanes) *
      0x1p-24f;
  std::array<float, kDims> out;
  for (int d = 0; d < kDims; ++d) out[d] = f[d];
  return out;
}

/// Point `index` of the scrambled four-dimensional sequence of `key`, its first kDims
/// coordinates as 32 bits.
template <int kDims = 4>
inline std::array<uint32_t, kDims> sample_bits(uint32_t index, uint64_t key) {
  return sample_bits_reversed<kDims>(reverse_bits(index), key);
}

/// sample_bits() as floats in [0, 1) (their top 24 bits).
template <int kDims = 4>
inline std::array<float, kDims> sample(uint32_t index, uint64_t key) {
  return sample_reversed<kDims>(reverse_bits(index), key);
}

}  // namespace rayfarm::sobol
