#pragma once
// Perfect specular reflection: a Dirac lobe, so eval and pdf are zero and only sample() finds it.
#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"

namespace rayfarm {

class MirrorBsdf {
 public:
  using Params = MirrorMaterial;
  bool is_specular() const { return true; }

  explicit MirrorBsdf(const MirrorMaterial& m) : reflectance_(m.reflectance) {}

  Vec3 eval(const Vec3& /*wo*/, const Vec3& /*wi*/) const { return Vec3(0.f); }
  float pdf(const Vec3& /*wo*/, const Vec3& /*wi*/) const { return 0.f; }
  bool sample(const Vec3& wo, float /*u_lobe*/, float /*u1*/, float /*u2*/, BsdfSample& out) const {
    if (wo.z == 0.f) return false;
    out.wi = reflect_z(wo);
    out.weight = reflectance_;
    out.pdf = 0.f;
    out.specular = true;
    return true;
  }

 private:
  Vec3 reflectance_;
};

}  // namespace rayfarm
