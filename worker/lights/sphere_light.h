#pragma once
// An emissive sphere, sampled uniformly by area.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "worker/lights/area_light.h"

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
  /// The primitive that emits, for SceneData::set_light_index.
  uint32_t geom() const { return kSphereGeometry; }
  uint32_t prim() const { return index_; }

  /// A uniform point on the sphere as seen from `ref`; p_select: the selection probability.
  bool sample(const Vec3& ref, float p_select, float u1, float u2, LightSample& out) const {
    return sample_with(ref, p_select, u1, u2, out, [this](const Vec3&) { return emission_; });
  }
  /// As sample(), the radiance at the point being radiance_at(n) of its unit normal.
  template <class RadianceAt>
  bool sample_with(const Vec3& ref, float p_select, float u1, float u2, LightSample& out,
                   const RadianceAt& radiance_at) const {
    const Vec3 n = sample_uniform_sphere(u1, u2);
    const Vec3 p = center_ + n * radius_;
    return finish_area_sample(ref, p, n, p_error_, area_, radiance_at(n), two_sided_, p_select,
                              out);
  }
  /// Density sample() has for reaching (p, n) from `ref`.
  float pdf(float p_select, const Vec3& ref, const Vec3& p, const Vec3& n) const {
    return area_light_pdf(p_select, area_, ref, p, n);
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
