#pragma once
// Parallel light from infinitely far away: a Dirac delta in direction, so only light sampling
// reaches it, and its shadow rays run to infinity.
#include <cstdint>
#include <optional>

#include "renderer/lights/light_sample.h"

namespace rayfarm {

class DeltaDirectionalLight {
 public:
  /// sample() reads none of its numbers (LightSet::reads_numbers()).
  static constexpr bool kReadsNumbers = false;
  /// The light of directional light `index`; nullopt when it emits no power. Its power is what
  /// crosses the disc of radius `scene_radius` facing it: the most the scene can receive.
  static std::optional<DeltaDirectionalLight> make(const Scene& scene, uint32_t index,
                                                   double scene_radius) {
    const DirectionalLight& d = scene.directional_lights[index];
    const double power = kPi * scene_radius * scene_radius * double(luminance(d.irradiance));
    if (!(power > 0.0)) return std::nullopt;
    return DeltaDirectionalLight(d, power);
  }

  double power() const { return power_; }

  /// The light as seen from anywhere: from -direction, with its irradiance (the integrator's
  /// BSDF value carries the cosine).
  bool sample(const Vec3& /*ref*/, float p_select, float /*u1*/, float /*u2*/,
              LightSample& out) const {
    out.wi = -direction_;
    out.radiance = irradiance_;
    out.pdf = p_select;
    out.delta = true;
    out.infinite = true;
    return true;
  }
  /// No BSDF ray has exactly this direction.
  float pdf(float /*p_select*/, const Vec3& /*ref*/, const Vec3& /*p*/, const Vec3& /*n*/) const {
    return 0.f;
  }

 private:
  DeltaDirectionalLight(const DirectionalLight& d, double power)
      : direction_(d.direction), irradiance_(d.irradiance), power_(power) {}

  Vec3 direction_, irradiance_;
  double power_ = 0.0;
};

}  // namespace rayfarm
