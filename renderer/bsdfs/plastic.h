#pragma once
// A diffuse base under a dielectric coating, smooth (alpha 0: a Dirac reflection) or rough (GGX
// or Beckmann microfacets). Light enters the coating, scatters diffusely off the base, and
// leaves; what the coating reflects back inside returns to the base, which the factor
// 1 / (1 - Ri) (or, `nonlinear`, 1 / (1 - Ri rho)) sums. A smooth coating passes 1 - F(mu) of the
// light at cosine mu and Ri is the Fresnel reflectance's diffuse average from inside; a rough
// one passes T(mu), what its micro-facets refract inwards, and Ri is its own reflectance's
// diffuse average from inside (rough_coat.h). On both sides (mirrored to wo's side).
#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"
#include "renderer/bsdfs/microfacet.h"
#include "renderer/bsdfs/microfacet_distribution.h"
#include "renderer/bsdfs/rough_coat.h"

namespace rayfarm {

/// Fraction of diffuse light inside a medium of index ior (outside 1) that its boundary reflects
/// back: the cosine-weighted hemispherical average of the Fresnel reflectance, from inside.
float internal_diffuse_reflectance(float ior);

class PlasticBsdf {
 public:
  using Params = PlasticMaterial;
  /// Light arrives only from wo's side: light selection may leave out lights behind it.
  static constexpr bool kReflectsOnly = true;

  explicit PlasticBsdf(const PlasticMaterial& m);

  /// Never: the diffuse base is not a Dirac lobe, even under a smooth coating.
  bool is_specular() const { return false; }
  /// f(wo, wi) * |cos(wi)|, the Dirac reflection of a smooth coating left out.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const;
  /// Density of sample()'s non-Dirac directions.
  float pdf(const Vec3& wo, const Vec3& wi) const;
  /// The coating's reflection (Dirac when smooth) or the base, chosen by their shares: the
  /// coat's reflectance (F, or 1 - T when rough) against the light it lets through times the
  /// base's luminance.
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const;

 private:
  float fresnel(float cos_i) const;
  /// Fraction of the light at cosine mu that the coating lets through to the base.
  float transmittance(float mu) const {
    return facets_.is_smooth() ? 1.f - fresnel(mu) : coat_.transmittance(mu);
  }
  /// What the coating reflects (r) and lets through (t) at cosine mu: r is F itself when smooth.
  void shares(float mu, float& r, float& t) const {
    if (facets_.is_smooth()) {
      r = fresnel(mu);
      t = 1.f - r;
    } else {
      t = coat_.transmittance(mu);
      r = 1.f - t;
    }
  }
  /// Probability that sample() picks the coating's reflection, for wo on the upper side, given
  /// what the coating reflects and lets through at wo.
  float coat_probability(float reflected_o, float transmitted_o) const;
  Vec3 eval_upper(const Vec3& wo, const Vec3& wi) const;
  float pdf_upper(const Vec3& wo, const Vec3& wi) const;

  float ior_;
  MicrofacetDistribution facets_;
  RoughCoatTable::Coat coat_;  // rough only
  Vec3 diffuse_;               // rho / (pi eta^2 (1 - Ri [rho]))
  float base_weight_;  // luminance of rho: the base's share before Fresnel
};

}  // namespace rayfarm
