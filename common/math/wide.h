#pragma once
// Vector arithmetic in double, for the few places where a float's range or rounding is not
// enough: a float's squared length underflows below ~1e-19 and overflows above ~1e19, and the
// cross product of edges of up to 1e17 overflows a float.
#include <cmath>

#include "common/math/vec3.h"

namespace rayfarm {

/// A 3-vector of doubles.
struct WideVec3 {
  double x = 0.0, y = 0.0, z = 0.0;
};

/// `a` converted exactly to double.
inline WideVec3 wide(const Vec3& a) { return {double(a.x), double(a.y), double(a.z)}; }
inline WideVec3 operator-(const WideVec3& a, const WideVec3& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline WideVec3 cross(const WideVec3& a, const WideVec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const WideVec3& a) { return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }
inline bool is_zero(const WideVec3& a) { return a.x == 0.0 && a.y == 0.0 && a.z == 0.0; }

/// (b - a) x (c - a), the edges taken in double: a triangle's normal times twice its area.
inline WideVec3 edge_cross(const Vec3& a, const Vec3& b, const Vec3& c) {
  return cross(wide(b) - wide(a), wide(c) - wide(a));
}

/// a / |a| with the length computed in double, so that it neither underflows nor overflows
/// (normalize() would then return NaN or zero).
inline Vec3 normalize_wide(const Vec3& a) {
  const double len = length(wide(a));
  return {static_cast<float>(a.x / len), static_cast<float>(a.y / len),
          static_cast<float>(a.z / len)};
}

}  // namespace rayfarm
