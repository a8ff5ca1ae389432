#include "renderer/samplers/sobol.h"

#ifdef RAYFARM_SOBOL_SSE41
#include <immintrin.h>
#endif

namespace rayfarm::sobol {

#ifdef RAYFARM_SOBOL_SSE41
namespace {

// reverse_word() in each lane: each byte's bits reversed through two nibble lookups (the low
// nibble reversed becomes the high one and the reverse), then the lane's bytes reversed.
[[gnu::target("sse4.1")]] inline __m128i reverse_lanes(__m128i x) {
  const __m128i low_nibbles = _mm_set1_epi8(0x0f);
  // rev4(n) << 4 and rev4(n), for n = 0..15 (rev4: the four bits of n in reverse order)
  const __m128i to_high = _mm_setr_epi8(
      0x00, static_cast<char>(0x80), 0x40, static_cast<char>(0xc0), 0x20, static_cast<char>(0xa0),
      0x60, static_cast<char>(0xe0), 0x10, static_cast<char>(0x90), 0x50, static_cast<char>(0xd0),
      0x30, static_cast<char>(0xb0), 0x70, static_cast<char>(0xf0));
  const __m128i to_low =
      _mm_setr_epi8(0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf);
  const __m128i bytes_reversed =
      _mm_or_si128(_mm_shuffle_epi8(to_high, _mm_and_si128(x, low_nibbles)),
                   _mm_shuffle_epi8(to_low, _mm_and_si128(_mm_srli_epi16(x, 4), low_nibbles)));
  const __m128i lane_bytes = _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12);
  return _mm_shuffle_epi8(bytes_reversed, lane_bytes);
}

}  // namespace

[[gnu::target("sse4.1")]] Lanes sample_lanes_sse41(uint32_t reversed_index, uint64_t key) {
  const Lanes v = sample_lanes_reversed(reversed_index, key);
  __m128i x;
  static_assert(sizeof x == sizeof v);
  __builtin_memcpy(&x, &v, sizeof x);
  x = reverse_lanes(x);
  Lanes out;
  __builtin_memcpy(&out, &x, sizeof out);
  return out;
}

const bool kHasSse41 = [] {
  __builtin_cpu_init();  // may run before libgcc's own initialisation of what the CPU has
  return __builtin_cpu_supports("sse4.1") != 0;
}();
#endif

}  // namespace rayfarm::sobol
