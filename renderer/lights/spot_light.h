#pragma once
// A spot light: a point light whose intensity falls off away from its axis. Full intensity
// within beam_width of the axis, then linearly in angle to zero at cutoff_angle (the profile of
// Mitsuba 3's "spot" emitter). A Dirac delta in position: only light sampling reaches it.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "renderer/lights/light_bounds.h"
#include "renderer/lights/light_sample.h"

namespace rayfarm {

class DeltaSpotLight {
 public:
  /// sample() reads none of its numbers (LightSet::reads_numbers()).
  static constexpr bool kReadsNumbers = false;
  /// The light of spot light `index`; nullopt when it emits no power.
  static std::optional<DeltaSpotLight> make(const Scene& scene, uint32_t index) {
    const SpotLight& s = scene.spot_lights[index];
    DeltaSpotLight light;
    light.position_ = s.position;
    light.axis_ = s.direction;
    light.intensity_ = s.intensity;
    light.cutoff_ = s.cutoff_deg * (kPi / 180.f);
    light.beam_ = std::min(s.beam_width_deg, s.cutoff_deg) * (kPi / 180.f);
    light.cos_cutoff_ = std::cos(light.cutoff_);
    light.cos_beam_ = std::cos(light.beam_);
    // Power: the falloff integrated over the cone (midpoint rule in theta; it only steers light
    // selection, so a close value is enough).
    constexpr int kSteps = 256;
    double cone = 0.0;
    for (int i = 0; i < kSteps; ++i) {
      const double theta = light.cutoff_ * (i + 0.5) / kSteps;
      cone += light.falloff_local(float(std::cos(theta)), float(theta)) * std::sin(theta);
    }
    cone *= 2.0 * kPi * light.cutoff_ / kSteps;
    light.power_ = cone * double(luminance(s.intensity));
    if (!(light.power_ > 0.0)) return std::nullopt;
    return light;
  }

  double power() const { return power_; }
  const Vec3& position() const { return position_; }
  /// The unit axis of the cone, away from the light.
  const Vec3& axis() const { return axis_; }
  /// The intensity along the axis.
  const Vec3& intensity() const { return intensity_; }
  /// Where the light tree finds it: a point that emits within the cutoff angle of its axis.
  LightBounds bounds() const {
    LightBounds b;
    b.lo = b.hi = position_;
    b.axis = axis_;
    b.cos_o = 1.f;
    // A little beyond the cutoff, in cosine (1e-6 is some 16 float steps near 1, which covers
    // the rounding of a direction even for the narrowest spot): rounding must never rule out a
    // point the spot lights.
    const float cos_cut =
        std::min(static_cast<float>(std::cos(std::min(double(cutoff_) + 1e-5, 3.14159265358979))),
                 cos_cutoff_);
    b.cos_e = std::max(-1.f, cos_cut - 1e-6f);
    b.intensity = luminance(intensity_);  // along the axis
    return b;
  }

  /// Fraction of the central intensity sent in the unit direction `w` (away from the light).
  float falloff(const Vec3& w) const {
    const float cos_theta = dot(w, axis_);
    return falloff_local(cos_theta, std::acos(std::clamp(cos_theta, -1.f, 1.f)));
  }

  /// The light as seen from `ref`; pdf is the selection probability p_select.
  bool sample(const Vec3& ref, float p_select, float /*u1*/, float /*u2*/, LightSample& out) const {
    const Vec3 d = position_ - ref;
    const float dist2 = dot(d, d);
    if (!(dist2 > 0.f)) return false;
    out.wi = d / std::sqrt(dist2);
    const float f = falloff(-out.wi);
    if (!(f > 0.f)) return false;
    out.radiance = intensity_ * (f / dist2);
    out.target = position_;
    out.pdf = p_select;
    out.delta = true;
    return true;
  }
  /// No ray hits a point: BSDF sampling never reaches it.
  float pdf(float /*p_select*/, const Vec3& /*ref*/, const Vec3& /*p*/, const Vec3& /*n*/) const {
    return 0.f;
  }

 private:
  DeltaSpotLight() = default;

  /// The falloff at angle theta from the axis (cos_theta its cosine).
  float falloff_local(float cos_theta, float theta) const {
    if (!(cos_theta > cos_cutoff_)) return 0.f;
    if (cos_theta >= cos_beam_) return 1.f;
    return std::clamp((cutoff_ - theta) / (cutoff_ - beam_), 0.f, 1.f);
  }

  Vec3 position_, axis_, intensity_;
  float cutoff_ = 0.f, beam_ = 0.f, cos_cutoff_ = 1.f, cos_beam_ = 1.f;
  double power_ = 0.0;
};

}  // namespace rayfarm
