#pragma once
// The anisotropic GGX (Trowbridge-Reitz) microfacet distribution with height-correlated Smith
// masking-shadowing and sampling of the visible normals, and the Fresnel reflectance of conductors.
// Local frame: z is the macro normal, alpha_u acts along x (the surface tangent), alpha_v along y.
#include "common/math/vec3.h"

namespace rayfarm {

/// Below this roughness a microfacet lobe is treated as smooth (a Dirac lobe): its peak would
/// exceed what float pdfs and weights can carry without overflow.
inline constexpr float kSmoothAlpha = 1e-4f;

class GgxDistribution {
 public:
  /// Roughness along x and y; each is raised to kSmoothAlpha so that one smooth axis of an
  /// otherwise rough surface keeps D finite.
  GgxDistribution(float alpha_u, float alpha_v);

  /// True when both roughnesses are below kSmoothAlpha: the caller must use a Dirac lobe.
  bool is_smooth() const { return smooth_; }

  /// Density of micro-normals per projected area: integral of D(wm) wm.z over the sphere is 1.
  float d(const Vec3& wm) const;
  /// Smith's Lambda for direction w (either side: uses |w.z|).
  float lambda(const Vec3& w) const;
  /// Masking of one direction.
  float g1(const Vec3& w) const { return 1.f / (1.f + lambda(w)); }
  /// Height-correlated masking-shadowing of two directions.
  float g(const Vec3& wo, const Vec3& wi) const { return 1.f / (1.f + lambda(wo) + lambda(wi)); }
  /// Density of the normals visible from w: G1(w) max(0, w.wm) D(wm) / |w.z|. w.z > 0.
  float visible_pdf(const Vec3& w, const Vec3& wm) const;
  /// A micro-normal drawn with density visible_pdf(w, .), for w.z > 0 (Heitz 2018).
  Vec3 sample_visible(const Vec3& w, float u1, float u2) const;

 private:
  float ax_, ay_;
  bool smooth_;
};

/// Mirror reflection of w about the micro-normal m.
inline Vec3 reflect_about(const Vec3& w, const Vec3& m) { return m * (2.f * dot(w, m)) - w; }

/// Unpolarised reflectance of a conductor of complex index eta + i k (relative to the outside) at
/// incidence cosine cos_i in [0, 1], exact (not Schlick).
float fresnel_conductor(float cos_i, float eta, float k);
/// Per channel.
Vec3 fresnel_conductor(float cos_i, const Vec3& eta, const Vec3& k);
/// Schlick's approximation F0 + (1 - F0) (1 - cos)^5.
Vec3 fresnel_schlick(const Vec3& f0, float cos_i);

}  // namespace rayfarm
