#pragma once
// A diffuse base under a dielectric coating, smooth (alpha 0: a Dirac reflection) or rough (GGX
// or Beckmann microfacets). Light enters the coating (1 - F(wi)), scatters diffusely off the base,
// and leaves (1 - F(wo)); what the coating reflects back inside returns to the base, which the
// factor 1 / (1 - Fdr_int) (or, `nonlinear`, 1 / (1 - Fdr_int rho)) sums. On both sides (mirrored
// to wo's side).
#include "common/scene/scene.h"
#include "worker/bsdfs/bsdf_sample.h"
#include "worker/bsdfs/microfacet.h"
#include "worker/bsdfs/microfacet_distribution.h"

namespace rayfarm {

/// Fraction of diffuse light inside a medium of index ior (outside 1) that its boundary reflects
/// back: the cosine-weighted hemispherical average of the Fresnel reflectance, from inside.
float internal_diffuse_reflectance(float ior);

class PlasticBsdf {
 public:
  using Params = PlasticMaterial;

  explicit PlasticBsdf(const PlasticMaterial& m);

  /// Never: the diffuse base is not a Dirac lobe, even under a smooth coating.
  bool is_specular() const { return false; }
  /// f(wo, wi) * |cos(wi)|, the Dirac reflection of a smooth coating left out.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const;
  /// Density of sample()'s non-Dirac directions.
  float pdf(const Vec3& wo, const Vec3& wi) const;
  /// The coating's reflection (Dirac when smooth) or the base, chosen by their Fresnel-weighted
  /// shares.
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const;

 private:
  float fresnel(float cos_i) const;
  /// Probability that sample() picks the coating's reflection, for wo on the upper side.
  float coat_probability(float fresnel_o) const;
  Vec3 eval_upper(const Vec3& wo, const Vec3& wi) const;
  float pdf_upper(const Vec3& wo, const Vec3& wi) const;

  float ior_;
  MicrofacetDistribution facets_;
  Vec3 diffuse_;       // rho / (pi eta^2 (1 - Fdr_int [rho]))
  float base_weight_;  // luminance of rho: the base's share before Fresnel
};

}  // namespace rayfarm
