#pragma once
// Smooth glass: Fresnel reflection or refraction, chosen by u_lobe. z > 0 is outside. Both lobes
// are Dirac, so eval and pdf are zero and only sample() finds them.
#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"

namespace rayfarm {

class DielectricBsdf {
 public:
  using Params = DielectricMaterial;
  bool is_specular() const { return true; }

  explicit DielectricBsdf(const DielectricMaterial& m) : ior_(m.ior), tint_(m.tint) {}

  Vec3 eval(const Vec3& /*wo*/, const Vec3& /*wi*/) const { return Vec3(0.f); }
  float pdf(const Vec3& /*wo*/, const Vec3& /*wi*/) const { return 0.f; }
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const;

 private:
  float ior_;
  Vec3 tint_;
};

/// Unpolarised Fresnel reflectance of a dielectric interface. cos_i > 0; eta = eta_t / eta_i.
/// Sets cos_t (> 0) unless there is total internal reflection (then returns 1).
float fresnel_dielectric(float cos_i, float eta, float& cos_t);

}  // namespace rayfarm
