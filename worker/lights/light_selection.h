#pragma once
// Which light a shading point samples: chosen with probability proportional to its emitted
// power, the same everywhere in the scene. Another strategy replaces this file.
#include <algorithm>
#include <cstdint>
#include <vector>

namespace rayfarm {

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
  int32_t choose(float u) const {
    if (cdf_.size() <= 1) return 0;
    const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), u);
    return static_cast<int32_t>(std::min<size_t>(it - cdf_.begin(), cdf_.size() - 1));
  }

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

}  // namespace rayfarm
