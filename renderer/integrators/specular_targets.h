#pragma once
// Sampling towards specular objects. Light that reaches a diffuse surface through glass or off
// a mirror (a caustic) can only be found by the surface's BSDF ray happening to enter the
// specular object and come out on an emitter: light sampling cannot see through it. At a
// non-specular vertex the path loop therefore mixes BSDF sampling with a second strategy, a
// direction uniform in the cone of one specular object's bounding sphere, and weights the
// outcome by the mixture's density (one-sample MIS, balance heuristic), so that the estimate
// stays unbiased whatever the objects are: directions into the cones are drawn more often and
// weigh less, every other direction weighs at most 1 / (1 - kShare) more.
//
// Which target a sample aims at is chosen in proportion to the targets' solid angles, so the
// cone strategy's density is uniform over the union of the cones: (number of cones holding the
// direction) / (sum of their solid angles). Everything here depends on the vertex alone, so a
// sample's numbers still depend only on (seed, pixel, sample index).
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "common/math/vec3.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// A specular object's bounding sphere.
struct SpecularTarget {
  Vec3 center;
  float radius = 0.f;
};

/// The cones of the targets seen from one vertex. Its arrays are left uninitialised (the path
/// loop declares one at every vertex); only the first `count` entries are set.
struct TargetCones {
  static constexpr uint32_t kMax = 8;
  uint32_t count = 0;
  std::array<float, kMax> axis_x, axis_y, axis_z;  ///< unit, towards the target's centre
  std::array<float, kMax> cos_max;        ///< cosine of the cone's half-angle
  std::array<float, kMax> one_minus_cos;  ///< 1 - cos_max, without cancellation
  std::array<float, kMax> cdf;            ///< running sums of the solid angles
  float total = 0.f;                      ///< sum of the solid angles

  Vec3 axis(uint32_t k) const { return {axis_x[k], axis_y[k], axis_z[k]}; }
  /// Density of the cone strategy at unit direction wi.
  float pdf(const Vec3& wi) const {
    uint32_t inside = 0;
    for (uint32_t k = 0; k < count; ++k) inside += dot(wi, axis(k)) >= cos_max[k];
    return inside ? static_cast<float>(inside) / total : 0.f;
  }
};

class SpecularTargets {
 public:
  /// Most targets kept: the largest bounding spheres when a scene has more specular objects.
  static constexpr uint32_t kMaxTargets = TargetCones::kMax;
  /// Targets whose cone is narrower (sin^2 of its half-angle below this: the object's radius
  /// under 3% of its distance, about 0.003 sr) are not aimed at from that point. Float rounding
  /// decides membership of directions within about 3e-7 of a cone's edge in cosine, wrongly for
  /// some; over a cone this wide that is 1 sample in 2000 near its edge.
  static constexpr float kMinSin2 = 1e-3f;
  /// Probability of the cone strategy at a vertex that sees at least one cone.
  static constexpr float kShare = 0.25f;

  SpecularTargets() = default;
  explicit SpecularTargets(std::vector<SpecularTarget> targets);
  /// The targets of a scene: the bounding sphere of each sphere and of each mesh (or instance of
  /// one) whose material `specular[index]` says is specular (for a mesh: of its specular
  /// triangles). Objects that move within the shutter are left out.
  static SpecularTargets of_scene(const Scene& scene, const std::vector<bool>& specular);

  bool empty() const { return targets_.empty(); }
  const std::vector<SpecularTarget>& targets() const { return targets_; }

  /// The cones seen from p. With a non-zero `side` (unit), cones wholly below the plane through p
  /// normal to it are left out (a surface that only reflects gets nothing from there).
  void cones(const Vec3& p, const Vec3& side, TargetCones& out) const {
    out.count = 0;
    out.total = 0.f;
    for (const SpecularTarget& t : targets_) {
      const Vec3 d = t.center - p;
      const float d2 = dot(d, d);
      const float r2 = t.radius * t.radius;
      // Inside or on it: no cone; nor below float's normal range, where the axis would lose
      // its length.
      if (!(d2 > r2 * 1.0001f) || !(d2 >= std::numeric_limits<float>::min())) continue;
      const float sin2 = r2 / d2;
      // A cone narrower than float's directions can resolve would not hold its own samples.
      if (!(sin2 > kMinSin2)) continue;
      const float inv_d = 1.f / std::sqrt(d2);
      const Vec3 axis = d * inv_d;
      const float cos_max = std::sqrt(std::max(0.f, 1.f - sin2));
      if (side.x != 0.f || side.y != 0.f || side.z != 0.f) {
        // Wholly below the plane: the angle from the plane to the axis exceeds the half-angle.
        if (dot(axis, side) < -std::sqrt(sin2)) continue;
      }
      const uint32_t k = out.count++;
      out.axis_x[k] = axis.x, out.axis_y[k] = axis.y, out.axis_z[k] = axis.z;
      out.cos_max[k] = cos_max;
      out.one_minus_cos[k] = sin2 / (1.f + cos_max);
      out.total += 2.f * kPi * out.one_minus_cos[k];
      out.cdf[k] = out.total;
    }
  }

  /// A direction from the cones: u0 picks the cone (by solid angle), u1 and u2 the direction,
  /// uniform in it. `cones` must hold at least one.
  static Vec3 sample(const TargetCones& cones, float u0, float u1, float u2) {
    const float pick = u0 * cones.total;
    uint32_t k = 0;
    while (k + 1 < cones.count && !(pick < cones.cdf[k])) ++k;
    const float one_minus_cos = u1 * cones.one_minus_cos[k];
    const float cos_t = 1.f - one_minus_cos;
    const float sin_t = std::sqrt(std::max(0.f, one_minus_cos * (2.f - one_minus_cos)));
    const float phi = 2.f * kPi * u2;
    const Frame frame(cones.axis(k));
    return frame.to_world(Vec3(sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t));
  }

 private:
  std::vector<SpecularTarget> targets_;
};

}  // namespace rayfarm
