#pragma once
// Deterministic random streams. A sample's stream is a function of (seed, pixel, sample index)
// only: never of the tile, the thread, the pass or the machine that renders it.
#include <cstdint>

namespace rayfarm {

/// SplitMix64 finaliser: a bijective 64-bit mix with good avalanche.
constexpr uint64_t mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// PCG32 (O'Neill, XSH-RR): 64-bit state, 32-bit outputs, selectable stream.
class Pcg32 {
 public:
  constexpr Pcg32(uint64_t state, uint64_t stream) : inc_((stream << 1u) | 1u) {
    next_u32();
    state_ += state;
    next_u32();
  }

  constexpr uint32_t next_u32() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ULL + inc_;
    const auto xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
    const auto rot = static_cast<uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31u));
  }

  /// Uniform float in [0, 1): 24 random bits, so 1 is never returned.
  constexpr float next_float() { return static_cast<float>(next_u32() >> 8) * 0x1p-24f; }

 private:
  uint64_t state_ = 0;
  uint64_t inc_;
};

/// The random stream of sample `sample` of pixel `pixel` (y * width + x) under `seed`.
inline Pcg32 sample_stream(uint64_t seed, uint64_t pixel, uint32_t sample) {
  // One PCG stream per (seed, pixel); samples start at scattered, distinct states within it.
  const uint64_t pixel_key = mix64(seed ^ mix64(pixel));
  return Pcg32(mix64(pixel_key + mix64(sample)), pixel_key);
}

}  // namespace rayfarm
