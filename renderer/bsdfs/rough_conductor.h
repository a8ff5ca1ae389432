#pragma once
// A metal: GGX or Beckmann microfacets with the conductor's Fresnel reflectance, on both sides
// (mirrored to wo's side). Roughness 0 on both axes is a smooth conductor, a Dirac lobe.
#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"
#include "renderer/bsdfs/microfacet.h"
#include "renderer/bsdfs/microfacet_distribution.h"

namespace rayfarm {

class RoughConductorBsdf {
 public:
  using Params = RoughConductorMaterial;
  /// Light arrives only from wo's side: light selection may leave out lights behind it.
  static constexpr bool kReflectsOnly = true;

  explicit RoughConductorBsdf(const RoughConductorMaterial& m)
      : m_(m), facets_(m.distribution, m.alpha_u, m.alpha_v) {}

  bool is_specular() const { return facets_.is_smooth(); }
  /// f(wo, wi) * |cos(wi)|; zero when smooth.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const;
  /// Solid-angle density with which sample() draws wi given wo; zero when smooth.
  float pdf(const Vec3& wo, const Vec3& wi) const;
  /// A visible micro-normal, and wo reflected about it; false when that falls below the surface.
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const;

  /// Reflectance at incidence cosine cos_i, times specular_reflectance.
  Vec3 fresnel(float cos_i) const;

 private:
  RoughConductorMaterial m_;
  MicrofacetDistribution facets_;
};

}  // namespace rayfarm
