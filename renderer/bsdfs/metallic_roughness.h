#pragma once
// The glTF 2.0 metallic-roughness BRDF (the specification's Appendix B), with KHR_materials_ior
// and KHR_materials_transmission: a mix, by `metallic`, of a metal (GGX with Schlick's Fresnel of
// F0 = base colour) and a dielectric (a Lambertian base colour, or by `transmission` a rough
// transmission lobe, under a GGX specular layer, mixed by Schlick's Fresnel of F0 from ior).
// The diffuse base is weighted by the layer's transmittance at wo and at wi rather than at the half
// vector (see eval_upper: the half-vector form does not conserve energy).
// Transmission is thin-walled, as the extension defines it without a volume: the transmitted
// lobe is the specular lobe mirrored through the surface, so rays leave unrefracted.
// Roughness 0 makes the specular and transmission lobes Dirac. On both sides (mirrored to wo's).
#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"
#include "renderer/bsdfs/microfacet.h"

namespace rayfarm {

class MetallicRoughnessBsdf {
 public:
  using Params = MetallicRoughnessMaterial;

  explicit MetallicRoughnessBsdf(const MetallicRoughnessMaterial& m);

  bool is_specular() const { return ggx_.is_smooth() && !(diffuse_share_ > 0.f); }
  /// f(wo, wi) * |cos(wi)|, Dirac lobes left out.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const;
  /// Density of sample()'s non-Dirac directions: the mixture of the lobes' densities.
  float pdf(const Vec3& wo, const Vec3& wi) const;
  /// Picks the specular, diffuse or transmission lobe by their estimated albedos at wo.
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const;

 private:
  struct Lobes {
    float spec, diffuse, trans;  // selection probabilities, summing to 1
  };
  Lobes lobes(float cos_o) const;
  /// The specular layer's reflectance at VdotH: metal and dielectric Fresnel mixed by metallic.
  Vec3 specular_fresnel(float v_dot_h) const;
  /// The dielectric layer's Schlick reflectance.
  float schlick(float cos_i) const;
  /// Weight of the base (diffuse or transmission) under the dielectric layer at VdotH.
  float dielectric_fresnel(float v_dot_h) const;
  Vec3 eval_upper(const Vec3& wo, const Vec3& wi) const;
  float pdf_upper(const Vec3& wo, const Vec3& wi) const;

  MetallicRoughnessMaterial m_;
  GgxDistribution ggx_;
  float f0_;  // dielectric reflectance at normal incidence, ((ior - 1) / (ior + 1))^2
  float diffuse_share_, trans_share_;  // (1 - metallic) (1 - or x transmission) lum(base)
};

}  // namespace rayfarm
