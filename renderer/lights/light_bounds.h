#pragma once
// What the light tree (light_tree.h) knows of one emitter or a group of them: the box that holds
// them, their intensity, and two cones: every normal lies within theta_o of `axis`, and each point
// emits within theta_e of its normal. From a shading point these give an estimate of how much of
// the group's light can arrive there, the importance that steers light selection. The estimate
// need not bound anything: a light that importance rules out at a point is left to BSDF
// sampling there (path_integrator.cpp), and a light it underrates is still chosen, less often.
#include <algorithm>
#include <cmath>

#include "common/math/vec3.h"

namespace rayfarm {

/// The form in which the light tree evaluates importance: the bounding sphere of the box, the
/// cones' sines precomputed. Float throughout but the power: coordinates stay within
/// kMaxCoordinate (1e17), so squared distances fit a float.
struct ImportanceBounds {
  Vec3 center;
  float r2 = 0.f;  ///< squared radius of the sphere around the box
  Vec3 axis{0.f, 0.f, 1.f};
  float cos_o = 1.f, sin_o = 0.f, cos_e = 0.f;
  double intensity = 0.0;
  bool two_sided = false;

  /// How much of the light of this group can reach `p`, a point that takes light from the side
  /// of the unit normal `n` only (or from every side: `n` the zero vector): intensity x the
  /// cosine at the emitters (the least angle between a normal in the cone and the direction to
  /// p) x the cosine at the receiver (likewise; 0 when the whole group is below its horizon),
  /// over the squared distance to the centre: the irradiance it would have from one emitter at
  /// the centre. Within the bounding sphere, the intensity over its squared radius
  /// (so that groups around p do not dominate without bound). 0 where no emitter of the group can
  /// face p.
  [[gnu::always_inline]] double importance(const Vec3& p, const Vec3& n) const {
    const Vec3 d = p - center;
    const float d2 = dot(d, d);
    // Inside the bounding sphere every direction may reach an emitter: no cosine bound.
    if (!(d2 > r2)) return intensity / std::max(double(r2), 1e-30);
    const Vec3 w = d * (1.f / std::sqrt(d2));  // from the centre to p
    // theta_b: half the angle the bounding sphere subtends from p.
    const float sin2_b = r2 / d2;
    const float sin_b = std::sqrt(sin2_b), cos_b = std::sqrt(std::max(0.f, 1.f - sin2_b));
    // The emitters' side: the angle from the axis to w, less theta_o and theta_b.
    float cos_w = dot(axis, w);
    if (two_sided) cos_w = std::abs(cos_w);
    const float sin_w = std::sqrt(std::max(0.f, 1.f - cos_w * cos_w));
    const float cos_x = cos_less(cos_w, sin_w, cos_o, sin_o);
    const float sin_x = sin_less(cos_w, sin_w, cos_o, sin_o);
    const float cos_p = cos_less(cos_x, sin_x, cos_b, sin_b);
    if (!(cos_p > cos_e)) return 0.0;
    // A group may light p from beyond 90 degrees off its normals (a spot of 90-degree cutoff,
    // within its slack): the cosine is floored, never negative or 0, so that it keeps a chance.
    float cosines = std::max(cos_p, kLeastCosine);
    // The receiver's side: the angle between its normal and the direction to the centre, less
    // theta_b; a little tolerance for the rounding of w against the light's own direction.
    if (n.x != 0.f || n.y != 0.f || n.z != 0.f) {
      const float cos_i = std::min(1.f, -dot(w, n) + kHorizonTolerance);
      const float sin_i = std::sqrt(std::max(0.f, 1.f - cos_i * cos_i));
      cosines *= std::max(0.f, cos_less(cos_i, sin_i, cos_b, sin_b));
    }
    return intensity * (double(cosines) / double(d2));
  }

  static constexpr float kLeastCosine = 1e-3f;
  static constexpr float kHorizonTolerance = 1e-5f;

  /// cos(max(0, a - b)) for angles a, b in [0, pi] given by their cosines and sines.
  static float cos_less(float cos_a, float sin_a, float cos_b, float sin_b) {
    if (cos_a >= cos_b) return 1.f;  // a <= b
    return cos_a * cos_b + sin_a * sin_b;
  }
  /// sin(max(0, a - b)), as cos_less.
  static float sin_less(float cos_a, float sin_a, float cos_b, float sin_b) {
    if (cos_a >= cos_b) return 0.f;
    return sin_a * cos_b - cos_a * sin_b;
  }
};

struct LightBounds {
  Vec3 lo, hi;               ///< box around the emitting points
  Vec3 axis{0.f, 0.f, 1.f};  ///< unit centre of the normals' cone
  float cos_o = 1.f;         ///< cos theta_o: the normals' spread around axis (-1: any)
  float cos_e = 0.f;         ///< cos theta_e: emission's spread around a normal (0: a hemisphere)
  /// The most radiant intensity (luminance, W/sr) that the group can send in any direction, the
  /// sum of its lights': radiance x area for a flat emitter (along its normal), radiance x pi r^2
  /// for a sphere, the intensity of a point or (along its axis) spot light; > 0. Intensity, not
  /// power, so that a point light and an area light of the same brightness at a point compare
  /// alike, and a narrow spot is not underrated by its small cone.
  double intensity = 0.0;
  bool two_sided = false;  ///< emits on both sides of its normals

  ImportanceBounds compact() const {
    ImportanceBounds b;
    b.center = (lo + hi) * 0.5f;
    const Vec3 e = hi - lo;
    b.r2 = 0.25f * dot(e, e);
    b.axis = axis;
    b.cos_o = cos_o;
    b.sin_o = std::sqrt(std::max(0.f, 1.f - cos_o * cos_o));
    b.cos_e = cos_e;
    b.intensity = intensity;
    b.two_sided = two_sided;
    return b;
  }
  /// ImportanceBounds::importance of these bounds.
  double importance(const Vec3& p, const Vec3& n) const { return compact().importance(p, n); }
};

/// The bounds of two groups together: the union of the boxes and of the normals' cones (the
/// smallest cone holding both, widened by a little for rounding), the wider emission spread.
LightBounds merge(const LightBounds& a, const LightBounds& b);

}  // namespace rayfarm
