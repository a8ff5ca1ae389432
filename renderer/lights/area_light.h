#pragma once
// The part of sampling that every area light shares: from a point chosen on the emitter to the
// sample seen from the shading point, and the density of reaching a point of the emitter.
#include <cmath>
#include <vector>

#include "renderer/lights/emission_footprint.h"
#include "renderer/lights/light_sample.h"
#include "renderer/scene_data.h"

namespace rayfarm {

/// How area lights read textured emission: the scene's textures, and per material the radiance
/// that stands for its emission in a light's power (a texture's mean times the factor).
struct EmissionTextures {
  const TextureSet* textures = nullptr;
  std::vector<Vec3> mean_radiance;  ///< per material; empty: every emission is a constant
  /// Where image textures emit, per triangle (emission_footprint.h); null: the means above.
  const EmissionFootprints* footprints = nullptr;
};

/// The radiance that stands for m's emission in a light's power.
inline Vec3 power_radiance(const Material& m, uint32_t material, const EmissionTextures* tex) {
  if (!m.emission.is_textured() || tex == nullptr || tex->mean_radiance.empty())
    return m.emission.value;
  return tex->mean_radiance[material];
}

/// Aims `out` at the point p (front normal n, error bound p_error) of an emitter that leaves
/// `radiance` there (its front side only unless two_sided): direction, radiance and shadow-ray
/// target, all but the density. Returns the squared distance and |cos| at the light, or false
/// when the sample carries nothing.
inline bool aim_at_emitter(const Vec3& ref, const Vec3& p, const Vec3& n, float p_error,
                           const Vec3& radiance, bool two_sided, LightSample& out, double& dist2,
                           float& cos_light) {
  // Distances in double: beyond ~1e19 their squares overflow a float, and the light would
  // silently never be sampled.
  const double dx = double(p.x) - ref.x, dy = double(p.y) - ref.y, dz = double(p.z) - ref.z;
  dist2 = dx * dx + dy * dy + dz * dz;
  if (!(dist2 > 0.0)) return false;
  const double dist = std::sqrt(dist2);
  out.wi = Vec3(static_cast<float>(dx / dist), static_cast<float>(dy / dist),
                static_cast<float>(dz / dist));
  cos_light = std::fabs(dot(n, out.wi));
  if (!(cos_light > 0.f)) return false;
  if (!two_sided && !(dot(n, out.wi) < 0.f)) return false;
  out.radiance = radiance;
  if (is_black(out.radiance)) return false;
  out.target = offset_ray_origin(p, p_error, dot(n, out.wi) < 0.f ? n : -n);
  out.delta = false;
  return true;
}

/// Completes `out` for the point p (front normal n, error bound p_error) chosen uniformly on an
/// emitter of area `area` that leaves `radiance` there (its front side only unless two_sided),
/// selected with probability p_select. False when the sample carries nothing.
inline bool finish_area_sample(const Vec3& ref, const Vec3& p, const Vec3& n, float p_error,
                               float area, const Vec3& radiance, bool two_sided, float p_select,
                               LightSample& out) {
  double dist2 = 0.0;
  float cos_light = 0.f;
  if (!aim_at_emitter(ref, p, n, p_error, radiance, two_sided, out, dist2, cos_light)) return false;
  out.pdf = static_cast<float>(p_select * dist2 / (double(cos_light) * area));
  return std::isfinite(out.pdf) && out.pdf > 0.f;
}

/// As finish_area_sample(), for a point whose direction was drawn from the solid-angle density
/// `density` (selection not included).
inline bool finish_solid_angle_sample(const Vec3& ref, const Vec3& p, const Vec3& n, float p_error,
                                      double density, const Vec3& radiance, bool two_sided,
                                      float p_select, LightSample& out) {
  double dist2 = 0.0;
  float cos_light = 0.f;
  if (!aim_at_emitter(ref, p, n, p_error, radiance, two_sided, out, dist2, cos_light)) return false;
  out.pdf = static_cast<float>(p_select * density);
  return std::isfinite(out.pdf) && out.pdf > 0.f;
}

/// Solid-angle density of reaching the point p (normal n) of an emitter of area `area`, selected
/// with probability p_select, from `ref`.
inline float area_light_pdf(float p_select, float area, const Vec3& ref, const Vec3& p,
                            const Vec3& n) {
  const double dx = double(p.x) - ref.x, dy = double(p.y) - ref.y, dz = double(p.z) - ref.z;
  const double dist2 = dx * dx + dy * dy + dz * dz;
  if (!(dist2 > 0.0)) return 0.f;
  const double cos_light = std::fabs(n.x * dx + n.y * dy + n.z * dz) / std::sqrt(dist2);
  if (!(cos_light > 0.0)) return 0.f;
  return static_cast<float>(p_select * dist2 / (cos_light * area));
}

}  // namespace rayfarm
