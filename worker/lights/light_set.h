#pragma once
// Every light of a scene (emissive triangles, emissive spheres, point lights) and the choice of
// one light per shading point with probability proportional to its emitted power.
#include <cstdint>
#include <vector>

#include "common/math/vec3.h"
#include "worker/scene_data.h"

namespace rayfarm {

/// A point chosen on a light, as seen from a shading point.
struct LightSample {
  Vec3 wi;           ///< unit direction from the shading point to the light
  Vec3 radiance;     ///< arriving radiance (area lights) or intensity / distance^2 (point lights)
  Vec3 target;       ///< end of the shadow ray (offset off the light's surface)
  float pdf = 0.f;   ///< solid-angle density times selection probability; selection only if delta
  bool delta = false;
};

class LightSet {
 public:
  /// Collects the lights of `data` and registers each emitter with data.set_light_index().
  explicit LightSet(SceneData& data);

  bool empty() const { return lights_.empty(); }
  size_t size() const { return lights_.size(); }
  size_t area_light_count() const { return lights_.size() - point_count_; }
  size_t point_light_count() const { return point_count_; }

  /// Chooses a light by power and a point on it. False when the sample carries nothing.
  bool sample(const Vec3& ref, float u_select, float u1, float u2, LightSample& out) const;
  /// Probability that sample() chooses light `light` (0 for -1: an emitter it cannot sample).
  float selection_probability(int32_t light) const;
  /// Density sample() would have had for reaching the emitter `light` at (p, n) from `ref`.
  float pdf(int32_t light, const Vec3& ref, const Vec3& p, const Vec3& n) const;

  /// Radiance leaving an emitter at a point with front normal n towards direction w.
  static Vec3 emitted(const Material& m, const Vec3& n, const Vec3& w);

 private:
  enum class Kind : uint8_t { kTriangle, kSphere, kPoint };
  struct Light {
    Kind kind;
    uint32_t geom = 0, prim = 0;  // mesh and triangle, or sphere index, or point light index
    float area = 0.f;
    Vec3 n;              // unit normal of a triangle, front side
    double power = 0.0;  // in double: luminance x area x pi overflows float for huge emitters
  };

  const SceneData* data_;
  std::vector<Light> lights_;
  std::vector<float> cdf_;  // cumulative power, normalised; cdf_.back() == 1
  size_t point_count_ = 0;
};

}  // namespace rayfarm
