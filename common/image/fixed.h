#pragma once
// Exact accumulation of samples. Each sample value is truncated once, deterministically, to a
// 128-bit fixed-point number with 2^-40 resolution; integer addition is then associative, so the
// sum over any grouping and order of sample ranges is the same bits. Every float32 sample of
// magnitude >= 2^-16 is represented exactly. See docs/determinism.md.
#include <cmath>
#include <cstdint>

namespace rayfarm {

__extension__ typedef __int128 Fixed;
__extension__ typedef unsigned __int128 UFixed;

inline constexpr int kFixedFractionBits = 40;
/// Largest sample magnitude accepted; larger samples are dropped and counted (docs/determinism.md).
inline constexpr double kMaxSampleValue = 4294967296.0;  // 2^32

/// Converts x (|x| <= 2^87 after scaling) to fixed point, truncating toward zero.
inline Fixed to_fixed(double x) {
  const double scaled = x * 1099511627776.0;  // 2^40, exact
  if (std::fabs(scaled) < 9.2e18) return static_cast<Fixed>(static_cast<int64_t>(scaled));
  return static_cast<Fixed>(scaled);
}

/// Converts a fixed-point value back to double (rounded to nearest). Most values fit 64 bits,
/// whose conversion rounds the same (to nearest) in one instruction instead of a library call.
inline double from_fixed(Fixed v) {
  const int64_t low = static_cast<int64_t>(v);
  const double whole = low == v ? static_cast<double>(low) : static_cast<double>(v);
  return whole * (1.0 / 1099511627776.0);
}

/// A fixed-point value's raw integer as long double: exact when it fits 64 bits (the long double
/// mantissa holds them all), rounded to nearest beyond, as a plain conversion would.
inline long double fixed_raw_long_double(Fixed v) {
  const int64_t low = static_cast<int64_t>(v);
  return low == v ? static_cast<long double>(low) : static_cast<long double>(v);
}

/// Low and high 64-bit halves, for the wire and for files.
inline uint64_t fixed_lo(Fixed v) { return static_cast<uint64_t>(static_cast<UFixed>(v)); }
inline int64_t fixed_hi(Fixed v) { return static_cast<int64_t>(v >> 64); }
inline Fixed fixed_from_parts(uint64_t lo, int64_t hi) {
  return static_cast<Fixed>((static_cast<UFixed>(static_cast<uint64_t>(hi)) << 64) | lo);
}

}  // namespace rayfarm
