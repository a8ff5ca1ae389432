#pragma once
// Which light a shading point samples. With few lights, each is chosen with probability
// proportional to its emitted power, the same everywhere in the scene. With more, the lights
// that have a place (emissive triangles and spheres, point and spot lights) are chosen through a
// light tree (light_tree.h) by their importance at the shading point, and the lights at infinity
// (directional lights, the environment) by their share of the power beside the tree's lights.
#include <algorithm>
#include <cstdint>
#include <optional>
#include <vector>

#include "renderer/lights/light_bounds.h"
#include "renderer/lights/light_tree.h"

namespace rayfarm {

/// The number that chooses a light: 32 uniform bits. Selection by power reads the top 24 (as a
/// float in [0, 1)); the tree all 32, remapped in double along its path.
struct SelectionNumber {
  uint32_t bits = 0;
  float as_float() const { return static_cast<float>(bits >> 8) * 0x1p-24f; }
  double as_double() const { return static_cast<double>(bits) * 0x1p-32; }
  /// The number whose float is u rounded down to 24 bits (u in [0, 1)), for callers that hold
  /// a float.
  static SelectionNumber from_float(float u) {
    return {static_cast<uint32_t>(std::clamp(double(u), 0.0, 0x1.fffffep-1) * 0x1p32)};
  }
};

/// How lights are chosen: kAuto (a light tree from kTreeMinLights lights with a place on),
/// or either strategy always (for tests and benchmarks).
enum class LightChoice : uint8_t { kAuto, kPower, kTree };
/// Fewest lights with a place for which kAuto builds a light tree. The tree's importance is an
/// irradiance estimate that knows nothing of glossy BSDFs; among a few lamps it ranks them no
/// better than their powers do, and its walk costs time at every vertex (docs/benchmarks.md,
/// "Light selection by a light tree": 0.8 to 1.4 times the efficiency of power selection on the
/// bundled scenes with 2 or 3 lights, 2.8 times on 129). Each emissive triangle counts: a quad
/// is two lights.
inline constexpr size_t kTreeMinLights = 8;

class PowerLightSelection {
 public:
  PowerLightSelection() = default;
  /// One entry per light: its power. Lights whose power is zero (e.g. pure blue below rounding)
  /// still get a small share.
  explicit PowerLightSelection(const std::vector<double>& powers) {
    double total = 0.0;
    for (const double p : powers) total += std::max(p, 1e-30);
    double running = 0.0;
    for (const double p : powers) {
      running += std::max(p, 1e-30);
      cdf_.push_back(static_cast<float>(running / total));
    }
    if (!cdf_.empty()) cdf_.back() = 1.f;
  }

  /// The light that the uniform number u chooses; there must be at least one light.
  template <class Real>
  int32_t choose(Real u) const {
    if (cdf_.size() <= 1) return 0;
    const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), u);
    return static_cast<int32_t>(std::min<size_t>(it - cdf_.begin(), cdf_.size() - 1));
  }

  /// Where choose() maps the interval of `light` from: its probabilities' sum before it.
  float lower(int32_t light) const { return light == 0 ? 0.f : cdf_[light - 1]; }

  /// Probability that choose() returns `light`; 0 for -1 (an emitter that cannot be sampled).
  float probability(int32_t light) const {
    if (light < 0) return 0.f;
    // The interval choose() maps to this light; for a light of negligible power the rounded cdf
    // may give it none, and then it is never chosen.
    const float lo = light == 0 ? 0.f : cdf_[light - 1];
    return cdf_[light] - lo;
  }

 private:
  std::vector<float> cdf_;  // cumulative power, normalised; cdf_.back() == 1
};

/// The choice of a light per shading point (p, n): by power alone, or through a light tree.
class LightSelection {
 public:
  LightSelection() = default;
  /// One entry per light: its power, and its bounds (nullopt for a light at infinity).
  LightSelection(const std::vector<double>& powers,
                 const std::vector<std::optional<LightBounds>>& bounds, LightChoice choice);

  bool uses_tree() const { return !tree_.empty(); }
  const LightTree& tree() const { return tree_; }

  /// Chooses a light for the point p with normal n (or zero) from the uniform number u, and
  /// its probability. False when none can be chosen there.
  [[gnu::always_inline]] bool choose(const Vec3& p, const Vec3& n, SelectionNumber number,
                                     int32_t& light, float& probability) const {
    if (tree_.empty()) {
      light = power_.choose(number.as_float());
      probability = power_.probability(light);
      return probability > 0.f;
    }
    const double u = number.as_double();
    const int32_t group = groups_.choose(u);
    const float p_group = groups_.probability(group);
    if (!(p_group > 0.f)) return false;
    if (group != 0) {
      light = infinite_[group - 1];
      probability = p_group;
      return true;
    }
    // The tree's interval of u, stretched back to [0, 1).
    const double v =
        std::clamp((u - groups_.lower(0)) / double(p_group), 0.0, 0x1.fffffffffffffp-1);
    float p_tree = 0.f;
    if (!tree_.choose(p, n, v, light, p_tree)) return false;
    probability = p_group * p_tree;
    return probability > 0.f;
  }

  /// Probability that choose() at (p, n) returns `light` (0 for -1).
  float probability(const Vec3& p, const Vec3& n, int32_t light) const {
    if (light < 0) return 0.f;
    if (tree_.empty()) return power_.probability(light);
    if (group_[light] == 0) return groups_.probability(0) * tree_.probability(p, n, light);
    return groups_.probability(group_[light]);
  }
  /// Probability of choosing `light`, a light at infinity: the same at every point.
  float infinite_probability(int32_t light) const {
    if (light < 0) return 0.f;
    if (tree_.empty()) return power_.probability(light);
    return group_[light] == 0 ? 0.f : groups_.probability(group_[light]);
  }
  /// Whether choose() can return `light` at some point: false for -1 and for a light of
  /// negligible power whose share rounds to nothing.
  bool selectable(int32_t light) const {
    if (light < 0) return false;
    if (tree_.empty()) return power_.probability(light) > 0.f;
    return groups_.probability(group_[light]) > 0.f;
  }

 private:
  PowerLightSelection power_;   // without a tree: over every light
  PowerLightSelection groups_;  // with one: entry 0 the tree, then each light at infinity
  LightTree tree_;
  std::vector<int32_t> infinite_;  // group - 1 -> light
  std::vector<int32_t> group_;     // light -> its group (0: in the tree)
};

}  // namespace rayfarm
