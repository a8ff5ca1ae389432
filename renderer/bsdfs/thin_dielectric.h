#pragma once
// A pane of glass of zero thickness: light is reflected about the normal or passes straight on,
// both Dirac lobes. The reflectance counts every bounce between the pane's two faces:
// R' = R + T^2 R / (1 - R^2) = 2 R / (1 + R) with T = 1 - R, R the Fresnel reflectance of one face.
// The pane is the same from both sides.
#include <cmath>

#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"
#include "renderer/bsdfs/dielectric.h"

namespace rayfarm {

class ThinDielectricBsdf {
 public:
  using Params = ThinDielectricMaterial;

  explicit ThinDielectricBsdf(const ThinDielectricMaterial& m) : ior_(m.ior), tint_(m.tint) {}

  bool is_specular() const { return true; }
  Vec3 eval(const Vec3& /*wo*/, const Vec3& /*wi*/) const { return Vec3(0.f); }
  float pdf(const Vec3& /*wo*/, const Vec3& /*wi*/) const { return 0.f; }
  bool sample(const Vec3& wo, float u_lobe, float /*u1*/, float /*u2*/, BsdfSample& out) const {
    if (wo.z == 0.f) return false;
    out.specular = true;
    out.pdf = 0.f;
    if (u_lobe < reflectance(std::fabs(wo.z))) {
      out.wi = reflect_z(wo);
      out.weight = Vec3(1.f);
    } else {
      out.wi = -wo;  // the two refractions cancel: the ray leaves parallel to itself
      out.weight = tint_;
    }
    return true;
  }

  /// The pane's reflectance R' at incidence cosine cos_i.
  float reflectance(float cos_i) const {
    float cos_t = 0.f;
    const float r = fresnel_dielectric(cos_i, ior_, cos_t);
    return r < 1.f ? 2.f * r / (1.f + r) : 1.f;
  }

 private:
  float ior_;
  Vec3 tint_;
};

}  // namespace rayfarm
