#pragma once
// Lambertian reflection, on both sides (mirrored to wo's side).
#include <cmath>

#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"

namespace rayfarm {

class DiffuseBsdf {
 public:
  using Params = DiffuseMaterial;
  /// Light arrives only from wo's side: light selection may leave out lights behind it.
  static constexpr bool kReflectsOnly = true;
  bool is_specular() const { return false; }

  explicit DiffuseBsdf(const DiffuseMaterial& m) : albedo_(m.albedo) {}

  /// f(wo, wi) * |cos(wi)|.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const {
    return wo.z * wi.z > 0.f ? albedo_ * (std::fabs(wi.z) * kInvPi) : Vec3(0.f);
  }
  /// Solid-angle density with which sample() draws wi given wo.
  float pdf(const Vec3& wo, const Vec3& wi) const {
    return wo.z * wi.z > 0.f ? std::fabs(wi.z) * kInvPi : 0.f;
  }
  /// Cosine-weighted direction on wo's side; u_lobe is not used.
  bool sample(const Vec3& wo, float /*u_lobe*/, float u1, float u2, BsdfSample& out) const {
    if (wo.z == 0.f) return false;
    const bool flip = wo.z < 0.f;
    const Vec3 wi = sample_cosine_hemisphere(u1, u2);
    if (wi.z <= 0.f) return false;
    out.wi = to_upper(wi, flip);
    out.weight = albedo_;
    out.pdf = wi.z * kInvPi;
    out.specular = false;
    return true;
  }

 private:
  Vec3 albedo_;
};

}  // namespace rayfarm
