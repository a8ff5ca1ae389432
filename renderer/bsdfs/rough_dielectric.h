#pragma once
// Rough glass: reflection and refraction through GGX or Beckmann microfacets (Walter et al. 2007).
// z > 0 is outside (index 1), z < 0 inside (index ior). Roughness 0 is the smooth dielectric; an
// index of 1 is an invisible interface whatever the roughness (every micro-facet passes light
// straight on), also a Dirac lobe.
#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"
#include "renderer/bsdfs/dielectric.h"
#include "renderer/bsdfs/microfacet.h"
#include "renderer/bsdfs/microfacet_distribution.h"

namespace rayfarm {

class RoughDielectricBsdf {
 public:
  using Params = RoughDielectricMaterial;

  explicit RoughDielectricBsdf(const RoughDielectricMaterial& m);

  bool is_specular() const { return facets_.is_smooth() || index_matched_; }
  /// f(wo, wi) * |cos(wi)|, reflection and transmission; radiance transmitted into the denser
  /// side is compressed by (n_o / n_i)^2, so f(wo, wi) / n_o^2 = f(wi, wo) / n_i^2.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const;
  /// Solid-angle density with which sample() draws wi given wo.
  float pdf(const Vec3& wo, const Vec3& wi) const;
  /// A visible micro-normal, then reflection with the Fresnel probability, else refraction.
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const;

 private:
  /// The micro-normal (z > 0) joining wo and wi, the Fresnel reflectance there and the relative
  /// index eta_i / eta_o for transmission; false when no micro-facet facing both exists.
  struct Half {
    Vec3 wm;
    float co, ci;  // wo.wm, wi.wm
    float fresnel;
    float eta;    // n(wi side) / n(wo side); 1 for reflection
    float denom;  // eta wi.wm + wo.wm, the refraction Jacobian's root (transmission only)
  };
  bool half_vector(const Vec3& wo, const Vec3& wi, Half& h) const;

  float ior_;
  Vec3 tint_;
  MicrofacetDistribution facets_;
  bool index_matched_;
  DielectricBsdf smooth_;
};

}  // namespace rayfarm
