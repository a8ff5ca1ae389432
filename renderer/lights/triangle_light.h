#pragma once
// An emissive triangle. Where it subtends a large enough solid angle from the shading point,
// directions are drawn uniformly in that solid angle (its spherical triangle), which removes the
// light's 1/r^2 and cosine from the estimate; where it looks small, or so large or thin that
// rounding would dominate the spherical triangle's angles, points are drawn uniformly by area.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "renderer/lights/area_light.h"
#include "renderer/lights/light_bounds.h"
#include "renderer/lights/solid_angle.h"

namespace rayfarm {

class TriangleLight {
 public:
  /// The light of triangle `tri` of mesh `mesh`; nullopt when its material does not emit or it
  /// cannot be sampled (no area in float). An emitter left out keeps light index -1, and BSDF
  /// rays then count it fully.
  static std::optional<TriangleLight> make(const Scene& scene, uint32_t mesh, uint32_t tri,
                                           const EmissionTextures* tex = nullptr) {
    const TriangleMesh& m = scene.meshes[mesh];
    const Material& mat = scene.materials[m.materials[tri]];
    if (!mat.is_emissive()) return std::nullopt;
    const Vec3& a = m.positions[m.indices[3 * tri]];
    const Vec3& b = m.positions[m.indices[3 * tri + 1]];
    const Vec3& c = m.positions[m.indices[3 * tri + 2]];
    const double area = triangle_area(a, b, c);
    Vec3 n;
    if (!(area > 0.0) || area > 3e38 || !triangle_normal(a, b, c, n)) return std::nullopt;
    const double sides = mat.two_sided ? 2.0 : 1.0;
    TriangleLight light;
    light.v0_ = a, light.v1_ = b, light.v2_ = c, light.n_ = n;
    light.area_ = static_cast<float>(area);
    const WideVec3 centroid = solid_angle::scale(
        solid_angle::add(solid_angle::add(wide(a), wide(b)), wide(c)), 1.0 / 3.0);
    light.centroid_ = centroid;
    for (const Vec3& v : {a, b, c})
      light.bound_radius_ = std::max(light.bound_radius_, length(wide(v) - centroid));
    light.area_d_ = area;
    light.p_error_ = triangle_point_error(a, b, c);
    light.emission_ = mat.emission.value;
    light.two_sided_ = mat.two_sided;
    light.geom_ = mesh, light.prim_ = tri;
    light.power_ =
        double(luminance(power_radiance(mat, m.materials[tri], tex))) * area * kPi * sides;
    return light;
  }

  /// Emitted power (luminance); in double: luminance x area x pi overflows float for huge ones.
  double power() const { return power_; }
  /// Sets the power from the mean luminance of the emitted radiance over the triangle (a
  /// textured emitter's, which the material's mean does not tell).
  void set_power_luminance(double mean) {
    power_ = mean * area_d_ * kPi * (two_sided_ ? 2.0 : 1.0);
  }
  /// Where the light tree (light_tree.h) finds it: the triangle's box, its normal, a hemisphere
  /// of emission on one side or both.
  LightBounds bounds() const {
    LightBounds b;
    b.lo = Vec3(std::min({v0_.x, v1_.x, v2_.x}), std::min({v0_.y, v1_.y, v2_.y}),
                std::min({v0_.z, v1_.z, v2_.z}));
    b.hi = Vec3(std::max({v0_.x, v1_.x, v2_.x}), std::max({v0_.y, v1_.y, v2_.y}),
                std::max({v0_.z, v1_.z, v2_.z}));
    b.axis = n_;
    b.cos_o = 1.f;
    b.cos_e = 0.f;
    b.intensity = power_ / (kPi * (two_sided_ ? 2.0 : 1.0));  // radiance x area
    b.two_sided = two_sided_;
    return b;
  }
  /// The primitive that emits (mesh and triangle), for SceneData::set_light_index.
  uint32_t geom() const { return geom_; }
  uint32_t prim() const { return prim_; }

  /// A point of the triangle as seen from `ref`; p_select: the selection probability.
  bool sample(const Vec3& ref, float p_select, float u1, float u2, LightSample& out) const {
    return sample_with(ref, p_select, u1, u2, out,
                       [this](float, float, float) { return emission_; });
  }
  /// As sample(), the radiance at the point being radiance_at(b0, b1, b2) of its barycentrics.
  template <class RadianceAt>
  bool sample_with(const Vec3& ref, float p_select, float u1, float u2, LightSample& out,
                   const RadianceAt& radiance_at) const {
    // A one-sided triangle seen from behind sends nothing, whichever point is drawn.
    const double height = height_above(ref);
    if (!two_sided_ && !(height > 0.0)) return false;
    SphericalView view;
    if (spherical_view(ref, height, view)) {
      float b1 = 0.f, b2 = 0.f;
      WideVec3 dir;
      if (!solid_angle::sample_spherical_triangle(view.a, view.b, view.c, view.area, u1, u2, dir) ||
          !barycentrics_along(ref, dir, b1, b2))
        return false;
      const float b0 = 1.f - b1 - b2;
      const Vec3 p = v0_ * b0 + v1_ * b1 + v2_ * b2;
      return finish_solid_angle_sample(ref, p, n_, p_error_, 1.0 / view.area,
                                       radiance_at(b0, b1, b2), two_sided_, p_select, out);
    }
    const float su = std::sqrt(u1);
    const float b0 = 1.f - su, b1 = u2 * su, b2 = 1.f - b0 - b1;
    const Vec3 p = v0_ * b0 + v1_ * b1 + v2_ * b2;
    return finish_area_sample(ref, p, n_, p_error_, area_, radiance_at(b0, b1, b2), two_sided_,
                              p_select, out);
  }
  /// Density sample() has for reaching (p, n) from `ref`.
  float pdf(float p_select, const Vec3& ref, const Vec3& p, const Vec3& n) const {
    SphericalView view;
    if (spherical_view(ref, height_above(ref), view))
      return static_cast<float>(p_select / view.area);
    return area_light_pdf(p_select, area_, ref, p, n);
  }

  /// Solid angles (steradians) within which sampling is by solid angle. Below the lower bound the
  /// density by area is nearly uniform in solid angle already (its 1/r^2 and cosine vary little
  /// over the triangle: for a square light the estimate's relative variance is 0.007 head-on at
  /// 0.4 sr, 0.015 at 0.14 sr seen off to one side), below the rest of a path's noise, while the
  /// spherical triangle costs some 800 more instructions a sample (docs/benchmarks.md). Near a
  /// hemisphere (2 pi) its angles approach pi and the sampling formulas lose their digits.
  static constexpr double kMinSolidAngle = 0.25;
  static constexpr double kMaxSolidAngle = 2.0 * solid_angle::kPiD - 0.02;

  /// The triangle as seen from a point: its spherical triangle and that one's area.
  struct SphericalView {
    WideVec3 a, b, c;  // unit directions to the vertices
    double area = 0.0;
  };
  /// Signed distance of `ref` from the triangle's plane, positive on its front side. In double:
  /// the corners of a huge triangle would leave a float difference nothing but rounding.
  double height_above(const Vec3& ref) const {
    return solid_angle::dot(wide(n_), wide(ref) - wide(v0_));
  }
  /// True when the triangle is sampled by solid angle from `ref` (height_above(ref): `height`),
  /// with its spherical triangle. A function of ref and the triangle alone, so that pdf()
  /// decides as sample() did.
  bool spherical_view(const Vec3& ref, double height, SphericalView& view) const {
    view.area = 0.0;
    // Most points see the triangle small, which a bound settles without the spherical
    // triangle: Omega = integral of h / d^3 dA over the triangle (h: the distance to its plane),
    // and every point of it is at least d_min = max(h, distance to the centroid - its bounding
    // radius) away, so Omega <= area h / d_min^3.
    const double h = std::fabs(height);
    if (area_d_ < kMinSolidAngle * h * h) return false;  // d_min >= h: no square root
    const WideVec3 r = wide(ref);
    const double d_min = std::max(h, length(centroid_ - r) - bound_radius_);
    if (area_d_ * h < kMinSolidAngle * d_min * d_min * d_min) return false;
    view.a = solid_angle::unit(wide(v0_) - r);
    view.b = solid_angle::unit(wide(v1_) - r);
    view.c = solid_angle::unit(wide(v2_) - r);
    // Corners seen in (nearly) the same or opposite directions leave an edge's great circle to
    // rounding (a huge triangle's far corners on either side of the point): by area then.
    constexpr double kParallel = 1.0 - 1e-8;
    if (std::fabs(solid_angle::dot(view.a, view.b)) > kParallel ||
        std::fabs(solid_angle::dot(view.b, view.c)) > kParallel ||
        std::fabs(solid_angle::dot(view.c, view.a)) > kParallel)
      return false;
    view.area = solid_angle::spherical_triangle_area(view.a, view.b, view.c);
    return view.area >= kMinSolidAngle && view.area <= kMaxSolidAngle;
  }

 private:
  TriangleLight() = default;

  /// Barycentrics (of v1 and v2) of the point where the ray from ref along dir meets the
  /// triangle's plane, pulled onto the triangle against rounding. False when the ray runs along
  /// the plane.
  bool barycentrics_along(const Vec3& ref, const WideVec3& dir, float& b1, float& b2) const {
    const WideVec3 e1 = wide(v1_) - wide(v0_), e2 = wide(v2_) - wide(v0_);
    const WideVec3 to_ref = wide(ref) - wide(v0_);
    const WideVec3 pv = cross(dir, e2);
    const double det = solid_angle::dot(e1, pv);
    if (!(std::fabs(det) > 0.0)) return false;
    double x1 = solid_angle::dot(to_ref, pv) / det;
    double x2 = solid_angle::dot(dir, cross(to_ref, e1)) / det;
    if (!std::isfinite(x1) || !std::isfinite(x2)) return false;
    x1 = std::max(0.0, x1), x2 = std::max(0.0, x2);
    if (x1 + x2 > 1.0) {
      const double sum = x1 + x2;
      x1 /= sum, x2 /= sum;
    }
    b1 = static_cast<float>(x1), b2 = static_cast<float>(x2);
    return true;
  }

  Vec3 v0_, v1_, v2_;
  Vec3 n_;  // unit normal, front side
  float area_ = 0.f, p_error_ = 0.f;
  WideVec3 centroid_;
  double bound_radius_ = 0.0;  // distance from the centroid to the farthest vertex
  double area_d_ = 0.0;
  Vec3 emission_;  // the constant emission (the factor, when textured)
  bool two_sided_ = false;
  uint32_t geom_ = 0, prim_ = 0;
  double power_ = 0.0;
};

}  // namespace rayfarm
