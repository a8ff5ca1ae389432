#pragma once
// An emissive triangle, sampled uniformly by area.
#include <cmath>
#include <cstdint>
#include <optional>

#include "worker/lights/area_light.h"

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
  /// The primitive that emits (mesh and triangle), for SceneData::set_light_index.
  uint32_t geom() const { return geom_; }
  uint32_t prim() const { return prim_; }

  /// A uniform point on the triangle as seen from `ref`; p_select: the selection probability.
  bool sample(const Vec3& ref, float p_select, float u1, float u2, LightSample& out) const {
    return sample_with(ref, p_select, u1, u2, out,
                       [this](float, float, float) { return emission_; });
  }
  /// As sample(), the radiance at the point being radiance_at(b0, b1, b2) of its barycentrics.
  template <class RadianceAt>
  bool sample_with(const Vec3& ref, float p_select, float u1, float u2, LightSample& out,
                   const RadianceAt& radiance_at) const {
    const float su = std::sqrt(u1);
    const float b0 = 1.f - su, b1 = u2 * su, b2 = 1.f - b0 - b1;
    const Vec3 p = v0_ * b0 + v1_ * b1 + v2_ * b2;
    return finish_area_sample(ref, p, n_, p_error_, area_, radiance_at(b0, b1, b2), two_sided_,
                              p_select, out);
  }
  /// Density sample() has for reaching (p, n) from `ref`.
  float pdf(float p_select, const Vec3& ref, const Vec3& p, const Vec3& n) const {
    return area_light_pdf(p_select, area_, ref, p, n);
  }

 private:
  TriangleLight() = default;

  Vec3 v0_, v1_, v2_;
  Vec3 n_;  // unit normal, front side
  float area_ = 0.f, p_error_ = 0.f;
  Vec3 emission_;  // the constant emission (the factor, when textured)
  bool two_sided_ = false;
  uint32_t geom_ = 0, prim_ = 0;
  double power_ = 0.0;
};

}  // namespace rayfarm
