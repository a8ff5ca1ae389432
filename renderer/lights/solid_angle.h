#pragma once
// Sampling directions uniformly in the solid angle an emitter subtends: the cone of directions
// that sees a sphere, and the spherical triangle a triangle projects to. In double: the cone's
// 1 - cos(theta_max) and a spherical triangle's angles lose every digit in float when the
// emitter is small or far.
#include <algorithm>
#include <cmath>

#include "common/math/wide.h"

namespace rayfarm::solid_angle {

inline constexpr double kPiD = 3.14159265358979323846;

inline WideVec3 add(const WideVec3& a, const WideVec3& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline WideVec3 scale(const WideVec3& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double dot(const WideVec3& a, const WideVec3& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
/// a / |a|; the zero vector for a zero (or non-finite) a.
inline WideVec3 unit(const WideVec3& a) {
  const double len = length(a);
  return len > 0.0 && std::isfinite(len) ? scale(a, 1.0 / len) : WideVec3{};
}
inline Vec3 narrow(const WideVec3& a) {
  return {static_cast<float>(a.x), static_cast<float>(a.y), static_cast<float>(a.z)};
}
/// The angle between unit vectors a and b, accurate near 0 and pi (where acos of the dot
/// product loses half the digits).
inline double angle_between(const WideVec3& a, const WideVec3& b) {
  return 2.0 * std::atan2(length(a - b), length(add(a, b)));
}

/// Two unit vectors completing the unit w to a right-handed frame (Duff et al. 2017).
inline void complete_frame(const WideVec3& w, WideVec3& e1, WideVec3& e2) {
  const double sign = std::copysign(1.0, w.z);
  const double a = -1.0 / (sign + w.z), b = w.x * w.y * a;
  e1 = {1.0 + sign * w.x * w.x * a, sign * b, -sign * w.x};
  e2 = {b, sign + w.y * w.y * a, -w.y};
}

/// 1 - sqrt(1 - x) for x in [0, 1], without the cancellation of the direct form when x is tiny
/// (a sphere far away: x = (r / d)^2).
inline double one_minus_sqrt_one_minus(double x) { return x / (1.0 + std::sqrt(1.0 - x)); }

/// The cone of directions from a point outside a sphere that sees it.
struct SphereCone {
  WideVec3 axis;               ///< unit, from the point to the centre
  double sin2_max = 0.0;       ///< sin^2 of the half-angle: (r / d)^2
  double one_minus_cos = 0.0;  ///< 1 - cos of the half-angle
  /// Its solid angle, 2 pi (1 - cos theta_max).
  double solid_angle() const { return 2.0 * kPiD * one_minus_cos; }
};

/// The unit normal of the point of the sphere (seen as `cone`) that the direction at polar angle
/// theta from the axis, 1 - cos(theta) = u1 (1 - cos theta_max), and azimuth 2 pi u2 meets
/// first. The point is centre + radius x normal.
inline WideVec3 sample_cone_normal(const SphereCone& cone, double u1, double u2) {
  const double omc = u1 * cone.one_minus_cos;
  const double cos_t = 1.0 - omc, sin2_t = omc * (2.0 - omc);
  // The angle alpha at the centre between the normal and the axis back to the point, from the
  // law of sines in the triangle (point, centre, hit): sin(alpha) follows from cos(alpha).
  const double sin_max = std::sqrt(cone.sin2_max);
  const double rest = std::max(0.0, 1.0 - std::min(1.0, sin2_t / cone.sin2_max));
  const double cos_a = std::clamp(sin2_t / sin_max + cos_t * std::sqrt(rest), -1.0, 1.0);
  const double sin_a = std::sqrt(std::max(0.0, 1.0 - cos_a * cos_a));
  const double phi = 2.0 * kPiD * u2;
  WideVec3 e1, e2;
  complete_frame(cone.axis, e1, e2);
  return add(add(scale(e1, sin_a * std::cos(phi)), scale(e2, sin_a * std::sin(phi))),
             scale(cone.axis, -cos_a));
}

/// The solid angle of the spherical triangle of unit vectors a, b, c (Van Oosterom and
/// Strackee's formula; accurate for small and for nearly hemispherical triangles).
inline double spherical_triangle_area(const WideVec3& a, const WideVec3& b, const WideVec3& c) {
  const double triple = std::fabs(dot(a, cross(b, c)));
  const double den = 1.0 + dot(a, b) + dot(b, c) + dot(c, a);
  return 2.0 * std::atan2(triple, den);
}

/// A direction (unit up to rounding) uniform in the spherical triangle a, b, c (unit vectors) of
/// area `area` (Arvo 1995: the area split off by u1 fixes the third vertex of a sub-triangle, u2
/// the point on the arc from b to it, with the density in z = cos that keeps the result uniform).
/// False when rounding leaves no direction.
inline bool sample_spherical_triangle(const WideVec3& a, const WideVec3& b, const WideVec3& c,
                                      double area, double u1, double u2, WideVec3& out) {
  // Unit normals of the great circles through each edge; the interior angle alpha at a lies
  // between the two circles that meet there. Its sine from the cross product and cosine from the
  // dot product keep their digits near 0 and pi alike, without an inverse trigonometric call.
  const WideVec3 n_ab = unit(cross(a, b)), n_ac = unit(cross(a, c));
  const double cos_alpha = dot(n_ab, n_ac), sin_alpha = length(cross(n_ab, n_ac));
  // The sub-triangle (a, b, c') of area u1 x area: c' on the arc from a to c.
  const double part = u1 * area;
  const double sin_part = std::sin(part), cos_part = std::cos(part);
  const double s = sin_part * cos_alpha - cos_part * sin_alpha;  // sin(part - alpha)
  const double t = cos_part * cos_alpha + sin_part * sin_alpha;  // cos(part - alpha)
  const double u = t - cos_alpha;
  const double v = s + sin_alpha * dot(a, b);
  const double den = (v * s + u * t) * sin_alpha;
  if (!(std::fabs(den) > 0.0)) return false;
  const double q = std::clamp(((v * t - u * s) * cos_alpha - v) / den, -1.0, 1.0);
  const WideVec3 c_perp = unit(c - scale(a, dot(c, a)));
  const WideVec3 c1 = add(scale(a, q), scale(c_perp, std::sqrt(std::max(0.0, 1.0 - q * q))));
  // The point on the arc from b to c', uniform in the sub-triangle's added sliver.
  const double z = 1.0 - u2 * (1.0 - dot(c1, b));
  const WideVec3 b_perp = unit(c1 - scale(b, dot(c1, b)));
  // Unit up to rounding: its length does not matter to the caller, which follows it to a plane.
  out = add(scale(b, z), scale(b_perp, std::sqrt(std::max(0.0, 1.0 - z * z))));
  return std::isfinite(out.x) && std::isfinite(out.y) && std::isfinite(out.z) &&
         (out.x != 0.0 || out.y != 0.0 || out.z != 0.0);
}

}  // namespace rayfarm::solid_angle
