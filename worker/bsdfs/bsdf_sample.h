#pragma once
// What every BSDF shares: the sampled-direction record and the local frame's helpers. BSDFs work
// in the local frame of the geometric normal (z up), with directions pointing away from the
// surface.
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

/// Cosine-weighted direction on the upper hemisphere (pdf cos / pi).
Vec3 sample_cosine_hemisphere(float u1, float u2);

}  // namespace rayfarm
