#pragma once
// What every light kind shares: the sample record and the radiance an emitter leaves.
#include "common/math/vec3.h"
#include "common/scene/scene.h"
#include "renderer/textures/texture_lookup.h"

namespace rayfarm {

/// A point chosen on a light, as seen from a shading point.
struct LightSample {
  Vec3 wi;          ///< unit direction from the shading point to the light
  Vec3 radiance;    ///< arriving radiance (area lights) or intensity / distance^2 (point lights)
  Vec3 target;      ///< end of the shadow ray (offset off the light's surface)
  float pdf = 0.f;  ///< solid-angle density times selection probability; selection only if delta
  bool delta = false;
  /// The light is at infinity (environment, directional): the shadow ray runs along wi without
  /// end, and `target` is unused.
  bool infinite = false;
};

/// Radiance leaving an emitter of material m at a point with front normal n towards direction w;
/// textured emission is read through `tex` (at the point's texture coordinates).
inline Vec3 emitted_radiance(const Material& m, const Vec3& n, const Vec3& w,
                             const TextureLookup& tex = {}) {
  if (!m.is_emissive() || !(m.two_sided || dot(n, w) > 0.f)) return Vec3(0.f);
  return m.emission.is_textured() ? tex.radiance(m.emission) : m.emission.value;
}

}  // namespace rayfarm
