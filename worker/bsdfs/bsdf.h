#pragma once
// Scattering at a surface point, in the local frame of the geometric normal (z up). A tagged
// struct, not a virtual class: it is built and evaluated per path vertex. Directions point away
// from the surface. Diffuse and Phong surfaces scatter on both sides (they mirror to wo's side);
// the dielectric uses z > 0 as outside.
#include <cmath>

#include "common/math/vec3.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// True in the benchmark build that knows only diffuse materials (option RAYFARM_DIFFUSE_ONLY,
/// bench/diffuse_only.sh): there every material test below is a compile-time constant, which
/// shows what the other materials cost a diffuse scene in the normal build.
#ifdef RAYFARM_DIFFUSE_ONLY
inline constexpr bool kDiffuseOnlyBuild = true;
#else
inline constexpr bool kDiffuseOnlyBuild = false;
#endif

/// A sampled direction and its throughput update f * |cos| / pdf.
struct BsdfSample {
  Vec3 wi;
  Vec3 weight;
  float pdf = 0.f;        ///< solid-angle density; meaningless (0) for specular samples
  bool specular = false;  ///< drawn from a Dirac lobe
};

class Bsdf {
 public:
  explicit Bsdf(const Material& m) : m_(&m) {}

  /// True when every lobe is a Dirac delta (light sampling cannot help).
  bool is_specular() const { return !kDiffuseOnlyBuild && m_->is_specular(); }
  /// f(wo, wi) * |cos(wi)|; zero for specular materials.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const {
    if (!kDiffuseOnlyBuild && m_->type != MaterialType::kDiffuse) return eval_other(wo, wi);
    return wo.z * wi.z > 0.f ? m_->albedo * (std::fabs(wi.z) * kInvPi) : Vec3(0.f);
  }
  /// Solid-angle density with which sample() draws wi given wo; zero for specular materials.
  float pdf(const Vec3& wo, const Vec3& wi) const {
    if (!kDiffuseOnlyBuild && m_->type != MaterialType::kDiffuse) return pdf_other(wo, wi);
    return wo.z * wi.z > 0.f ? std::fabs(wi.z) * kInvPi : 0.f;
  }
  /// Draws wi from three uniform numbers; false when no direction carries energy.
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const;

 private:
  // The non-diffuse cases; diffuse, the common one, is inline above.
  Vec3 eval_other(const Vec3& wo, const Vec3& wi) const;
  float pdf_other(const Vec3& wo, const Vec3& wi) const;

  const Material* m_;
};

/// Unpolarised Fresnel reflectance of a dielectric interface. cos_i > 0; eta = eta_t / eta_i.
/// Sets cos_t (> 0) unless there is total internal reflection (then returns 1).
float fresnel_dielectric(float cos_i, float eta, float& cos_t);

/// Cosine-weighted direction on the upper hemisphere (pdf cos / pi).
Vec3 sample_cosine_hemisphere(float u1, float u2);

}  // namespace rayfarm
