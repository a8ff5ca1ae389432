#pragma once
// The anisotropic Beckmann microfacet distribution (a Gaussian of the micro-surface's slopes) with
// height-correlated Smith masking-shadowing from its exact Lambda, and exact sampling of the
// visible normals. Same frame and roles as GgxDistribution (microfacet.h): z is the macro normal,
// alpha_u acts along x, alpha_v along y.
#include "common/math/vec3.h"

namespace rayfarm {

class BeckmannDistribution {
 public:
  /// Roughness (the slopes' RMS times sqrt 2) along x and y; each is raised to kSmoothAlpha so
  /// that one smooth axis of an otherwise rough surface keeps D finite.
  BeckmannDistribution(float alpha_u, float alpha_v);

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
  /// A micro-normal drawn with density visible_pdf(w, .), for w.z > 0: the visible slopes are
  /// drawn by inverting their distribution numerically (to double precision), so the density
  /// is exactly visible_pdf and not an approximation of it.
  Vec3 sample_visible(const Vec3& w, float u1, float u2) const;

 private:
  float ax_, ay_;
  bool smooth_;
};

/// The slope x < cos / sin of a unit-roughness Beckmann surface seen at incidence angle theta
/// (in the plane of x) whose distribution function is u: density proportional to
/// (cos - x sin) exp(-x^2). With sin 0 it is the quantile of the normal law of variance 1/2.
double beckmann_visible_slope(double cos_theta, double sin_theta, double u);

}  // namespace rayfarm
