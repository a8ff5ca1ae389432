#pragma once
// Affine transforms of shapes (docs/scene-format.md, "Transforms"), kept in double so that a chain
// of scene-file operations loses nothing a float point would notice.
#include <array>
#include <cmath>

#include "common/math/vec3.h"
#include "common/math/wide.h"

namespace rayfarm {

/// x' = A x + b, with A a 3x3 matrix (row-major) and b a translation.
class Transform {
 public:
  /// The identity.
  Transform() = default;
  /// From the 3x4 rows [A | b].
  explicit Transform(const std::array<double, 12>& rows) : m_(rows) {}

  static Transform translate(const WideVec3& t) {
    return Transform({1, 0, 0, t.x, 0, 1, 0, t.y, 0, 0, 1, t.z});
  }
  static Transform scale(const WideVec3& s) {
    return Transform({s.x, 0, 0, 0, 0, s.y, 0, 0, 0, 0, s.z, 0});
  }
  /// Rotation by `degrees` about the unit `axis`, counter-clockwise seen from its tip (right hand).
  static Transform rotate(const WideVec3& axis, double degrees) {
    const double a = degrees * (3.14159265358979323846 / 180.0);
    const double c = std::cos(a), s = std::sin(a), t = 1.0 - c;
    const double x = axis.x, y = axis.y, z = axis.z;
    return Transform({t * x * x + c, t * x * y - s * z, t * x * z + s * y, 0,  //
                      t * x * y + s * z, t * y * y + c, t * y * z - s * x, 0,  //
                      t * x * z - s * y, t * y * z + s * x, t * z * z + c, 0});
  }
  /// Places an object's local frame at `eye` with its +z axis towards `target` and its +y axis
  /// as close to `up` as is orthogonal; +x is y x z. The three must not be degenerate (checked by
  /// the reader).
  static Transform look_at(const WideVec3& eye, const WideVec3& target, const WideVec3& up) {
    const WideVec3 z = unit(target - eye);
    const WideVec3 x = unit(cross(up, z));
    const WideVec3 y = cross(z, x);
    return Transform({x.x, y.x, z.x, eye.x, x.y, y.y, z.y, eye.y, x.z, y.z, z.z, eye.z});
  }

  /// This transform followed by `next` (next ∘ this).
  Transform then(const Transform& next) const {
    Transform r;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 4; ++j) {
        double v = j == 3 ? next.at(i, 3) : 0.0;
        for (int k = 0; k < 3; ++k) v += next.at(i, k) * at(k, j);
        r.m_[4 * i + j] = v;
      }
    }
    return r;
  }

  double at(int row, int col) const { return m_[4 * row + col]; }
  double determinant() const {
    return at(0, 0) * (at(1, 1) * at(2, 2) - at(1, 2) * at(2, 1)) -
           at(0, 1) * (at(1, 0) * at(2, 2) - at(1, 2) * at(2, 0)) +
           at(0, 2) * (at(1, 0) * at(2, 1) - at(1, 1) * at(2, 0));
  }
  bool is_identity() const { return m_ == Transform().m_; }

  WideVec3 point(const WideVec3& p) const {
    return {at(0, 0) * p.x + at(0, 1) * p.y + at(0, 2) * p.z + at(0, 3),
            at(1, 0) * p.x + at(1, 1) * p.y + at(1, 2) * p.z + at(1, 3),
            at(2, 0) * p.x + at(2, 1) * p.y + at(2, 2) * p.z + at(2, 3)};
  }
  WideVec3 vector(const WideVec3& v) const {
    return {at(0, 0) * v.x + at(0, 1) * v.y + at(0, 2) * v.z,
            at(1, 0) * v.x + at(1, 1) * v.y + at(1, 2) * v.z,
            at(2, 0) * v.x + at(2, 1) * v.y + at(2, 2) * v.z};
  }
  /// A normal: multiplied by the cofactor matrix (the inverse transpose times the determinant),
  /// which keeps it perpendicular to transformed surfaces; not normalised. A mirroring transform
  /// (negative determinant) flips it, as it flips a triangle's winding.
  WideVec3 normal(const WideVec3& n) const {
    auto cof = [this](int r, int c) {
      const int r0 = (r + 1) % 3, r1 = (r + 2) % 3, c0 = (c + 1) % 3, c1 = (c + 2) % 3;
      return at(r0, c0) * at(r1, c1) - at(r0, c1) * at(r1, c0);
    };
    return {cof(0, 0) * n.x + cof(0, 1) * n.y + cof(0, 2) * n.z,
            cof(1, 0) * n.x + cof(1, 1) * n.y + cof(1, 2) * n.z,
            cof(2, 0) * n.x + cof(2, 1) * n.y + cof(2, 2) * n.z};
  }

  /// The common scale s when A = s R with R a rotation (possibly mirroring), within a relative
  /// 1e-6; 0 when A stretches some directions more than others (or is singular).
  double uniform_scale() const {
    const WideVec3 c0{at(0, 0), at(1, 0), at(2, 0)}, c1{at(0, 1), at(1, 1), at(2, 1)},
        c2{at(0, 2), at(1, 2), at(2, 2)};
    const double s0 = dot(c0, c0), s1 = dot(c1, c1), s2 = dot(c2, c2);
    const double tol = 1e-6 * std::max(s0, std::max(s1, s2));
    if (!(s0 > 0.0) || std::fabs(s0 - s1) > tol || std::fabs(s0 - s2) > tol ||
        std::fabs(dot(c0, c1)) > tol || std::fabs(dot(c0, c2)) > tol ||
        std::fabs(dot(c1, c2)) > tol) {
      return 0.0;
    }
    return std::sqrt(s0);
  }

 private:
  static double dot(const WideVec3& a, const WideVec3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
  }
  static WideVec3 unit(const WideVec3& a) {
    const double len = length(a);
    return {a.x / len, a.y / len, a.z / len};
  }
  std::array<double, 12> m_{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
};

}  // namespace rayfarm
