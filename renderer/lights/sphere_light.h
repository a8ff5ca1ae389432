#pragma once
// An emissive sphere. From outside it, directions are drawn uniformly in the cone that sees it
// (the visible cap, every sample lit by a one-sided sphere, and no 1/r^2 or cosine left in the
// estimate); from inside or on it, points uniformly by area.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "renderer/lights/area_light.h"
#include "renderer/lights/light_bounds.h"
#include "renderer/lights/solid_angle.h"

namespace rayfarm {

class SphereLight {
 public:
  /// The light of sphere `index`; nullopt when its material does not emit or its area overflows.
  static std::optional<SphereLight> make(const Scene& scene, uint32_t index,
                                         const EmissionTextures* tex = nullptr) {
    const Sphere& s = scene.spheres[index];
    const Material& mat = scene.materials[s.material];
    if (!mat.is_emissive()) return std::nullopt;
    const double r = s.radius;
    const double area = 4.0 * kPi * r * r;
    if (!(area > 0.0) || area > 3e38) return std::nullopt;
    const double sides = mat.two_sided ? 2.0 : 1.0;
    SphereLight light;
    light.center_ = s.center;
    light.radius_ = s.radius;
    light.area_ = static_cast<float>(area);
    light.p_error_ = sphere_point_error(s.center, s.radius);
    light.emission_ = mat.emission.value;
    light.two_sided_ = mat.two_sided;
    light.index_ = index;
    light.power_ = double(luminance(power_radiance(mat, s.material, tex))) * area * kPi * sides;
    return light;
  }

  double power() const { return power_; }
  /// Where the light tree finds it: the sphere's box; its normals point every way.
  LightBounds bounds() const {
    LightBounds b;
    b.lo = center_ - Vec3(radius_);
    b.hi = center_ + Vec3(radius_);
    b.cos_o = -1.f;
    b.cos_e = 0.f;
    b.intensity = power_ / (4.0 * kPi * (two_sided_ ? 2.0 : 1.0));  // radiance x pi r^2
    b.two_sided = two_sided_;
    return b;
  }
  /// The primitive that emits, for SceneData::set_light_index.
  uint32_t geom() const { return kSphereGeometry; }
  uint32_t prim() const { return index_; }

  /// A point of the sphere as seen from `ref`; p_select: the selection probability.
  bool sample(const Vec3& ref, float p_select, float u1, float u2, LightSample& out) const {
    return sample_with(ref, p_select, u1, u2, out, [this](const Vec3&) { return emission_; });
  }
  /// As sample(), the radiance at the point being radiance_at(n) of its unit normal.
  template <class RadianceAt>
  bool sample_with(const Vec3& ref, float p_select, float u1, float u2, LightSample& out,
                   const RadianceAt& radiance_at) const {
    solid_angle::SphereCone cone;
    if (visible_cone(ref, cone)) {
      const WideVec3 nw = solid_angle::sample_cone_normal(cone, u1, u2);
      const Vec3 n = solid_angle::narrow(nw);
      const Vec3 p =
          solid_angle::narrow(solid_angle::add(wide(center_), solid_angle::scale(nw, radius_)));
      return finish_solid_angle_sample(ref, p, n, p_error_, 1.0 / cone.solid_angle(),
                                       radiance_at(n), two_sided_, p_select, out);
    }
    const Vec3 n = sample_uniform_sphere(u1, u2);
    const Vec3 p = center_ + n * radius_;
    return finish_area_sample(ref, p, n, p_error_, area_, radiance_at(n), two_sided_, p_select,
                              out);
  }
  /// Density sample() has for reaching (p, n) from `ref`.
  float pdf(float p_select, const Vec3& ref, const Vec3& p, const Vec3& n) const {
    solid_angle::SphereCone cone;
    if (!visible_cone(ref, cone)) return area_light_pdf(p_select, area_, ref, p, n);
    // From outside, only the cap facing `ref` is ever drawn. A ray's first hit lies on it; a
    // point clearly behind it (reached through the sphere) has density 0, so that MIS gives its
    // emission to the BSDF ray alone.
    const double dx = double(ref.x) - p.x, dy = double(ref.y) - p.y, dz = double(ref.z) - p.z;
    const double facing = n.x * dx + n.y * dy + n.z * dz;
    if (facing < -1e-3 * std::sqrt(dx * dx + dy * dy + dz * dz)) return 0.f;
    return static_cast<float>(p_select / cone.solid_angle());
  }

  /// True when `ref` lies clearly outside the sphere, with the cone that sees the sphere from
  /// there; else (inside, on, or within rounding of it) sampling is by area. A function of ref
  /// and the sphere alone, so that pdf() decides as sample() did.
  bool visible_cone(const Vec3& ref, solid_angle::SphereCone& cone) const {
    const WideVec3 to_center = wide(center_) - wide(ref);
    const double d = length(to_center), r = radius_;
    // A point computed on the surface lies within its rounding error p_error_ of it.
    if (!(d > r + std::max(1e-5 * r, 2.0 * double(p_error_)))) return false;
    cone.axis = solid_angle::scale(to_center, 1.0 / d);
    cone.sin2_max = (r / d) * (r / d);
    cone.one_minus_cos = solid_angle::one_minus_sqrt_one_minus(cone.sin2_max);
    return cone.one_minus_cos > 0.0 && std::isfinite(cone.one_minus_cos);
  }

 private:
  SphereLight() = default;

  static Vec3 sample_uniform_sphere(float u1, float u2) {
    const float z = 1.f - 2.f * u1;
    const float r = std::sqrt(std::max(0.f, 1.f - z * z));
    const float phi = 2.f * kPi * u2;
    return {r * std::cos(phi), r * std::sin(phi), z};
  }

  Vec3 center_;
  float radius_ = 0.f, area_ = 0.f, p_error_ = 0.f;
  Vec3 emission_;  // the constant emission (the factor, when textured)
  bool two_sided_ = false;
  uint32_t index_ = 0;
  double power_ = 0.0;
};

}  // namespace rayfarm
