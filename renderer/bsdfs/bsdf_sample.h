#pragma once
// What every BSDF shares: the sampled-direction record and the local frame's helpers. BSDFs work
// in the local frame of the geometric normal (z up), with directions pointing away from the
// surface.
#include <algorithm>
#include <cmath>

#include "common/math/vec3.h"

namespace rayfarm {

/// A sampled direction and its throughput update f * |cos| / pdf.
struct BsdfSample {
  Vec3 wi;
  Vec3 weight;
  float pdf = 0.f;        ///< solid-angle density; meaningless (0) for specular samples
  bool specular = false;  ///< drawn from a Dirac lobe
  /// eta_t / eta_i of a refraction (the weight carries the radiance's 1 / eta^2); 1 otherwise.
  /// Throughput roulette undoes that factor so that it judges the path, not the medium.
  float eta = 1.f;
};

/// For two-sided surfaces: w mirrored to the upper hemisphere when `flip` (wo below).
inline Vec3 to_upper(const Vec3& w, bool flip) { return flip ? Vec3{w.x, w.y, -w.z} : w; }
/// Mirror reflection about the normal.
inline Vec3 reflect_z(const Vec3& w) { return {-w.x, -w.y, w.z}; }

/// cos(x) and sin(x) for |x| <= pi/4 by their Taylor series to x^8 and x^9: within 3e-8 of the
/// exact values there, without the range reduction and the call of std::sin and std::cos.
inline void cos_sin_octant(float x, float& c, float& s) {
  const float x2 = x * x;
  c = 1.f + x2 * (-1.f / 2 + x2 * (1.f / 24 + x2 * (-1.f / 720 + x2 * (1.f / 40320))));
  s = x * (1.f + x2 * (-1.f / 6 + x2 * (1.f / 120 + x2 * (-1.f / 5040 + x2 * (1.f / 362880)))));
}

/// Cosine-weighted direction on the upper hemisphere (pdf cos / pi). Inlined: every diffuse
/// bounce draws one.
inline Vec3 sample_cosine_hemisphere(float u1, float u2) {
  // Concentric disk mapping (Shirley-Chiu), then lift to the hemisphere. The disk's angle is
  // within pi/4 of the x axis (first case) or of the y axis (second), where cos_sin_octant()
  // serves.
  const float a = 2.f * u1 - 1.f, b = 2.f * u2 - 1.f;
  if (a == 0.f && b == 0.f) return {0.f, 0.f, 1.f};
  float x, y;
  if (std::fabs(a) > std::fabs(b)) {
    float c, s;
    cos_sin_octant((kPi / 4.f) * (b / a), c, s);
    x = a * c, y = a * s;
  } else {
    float c, s;  // the angle is pi/2 - t: its cosine is sin(t), its sine cos(t)
    cos_sin_octant((kPi / 4.f) * (a / b), c, s);
    x = b * s, y = b * c;
  }
  return {x, y, std::sqrt(std::max(0.f, 1.f - x * x - y * y))};
}

}  // namespace rayfarm
