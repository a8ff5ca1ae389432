#pragma once
// The microfacet distribution a rough BSDF was given: GGX or Beckmann, chosen per material. A
// tag and one branch per call rather than a template parameter of each BSDF: the branch goes the
// same way at every vertex of a material, so it costs next to nothing, while a template would
// double the rough kinds in the Bsdf variant that every vertex dispatches over.
#include "common/scene/scene.h"
#include "renderer/bsdfs/beckmann.h"
#include "renderer/bsdfs/microfacet.h"

namespace rayfarm {

class MicrofacetDistribution {
 public:
  MicrofacetDistribution(MicrofacetType type, float alpha_u, float alpha_v)
      : beckmann_(type == MicrofacetType::kBeckmann),
        ggx_(alpha_u, alpha_v),
        bk_(alpha_u, alpha_v) {}

  // The same contracts as GgxDistribution's (microfacet.h).
  bool is_smooth() const { return ggx_.is_smooth(); }
  float d(const Vec3& wm) const { return beckmann_ ? bk_.d(wm) : ggx_.d(wm); }
  float lambda(const Vec3& w) const { return beckmann_ ? bk_.lambda(w) : ggx_.lambda(w); }
  float g1(const Vec3& w) const { return beckmann_ ? bk_.g1(w) : ggx_.g1(w); }
  float g(const Vec3& wo, const Vec3& wi) const {
    return beckmann_ ? bk_.g(wo, wi) : ggx_.g(wo, wi);
  }
  float visible_pdf(const Vec3& w, const Vec3& wm) const {
    return beckmann_ ? bk_.visible_pdf(w, wm) : ggx_.visible_pdf(w, wm);
  }
  Vec3 sample_visible(const Vec3& w, float u1, float u2) const {
    return beckmann_ ? bk_.sample_visible(w, u1, u2) : ggx_.sample_visible(w, u1, u2);
  }

 private:
  bool beckmann_;
  GgxDistribution ggx_;
  BeckmannDistribution bk_;
};

}  // namespace rayfarm
