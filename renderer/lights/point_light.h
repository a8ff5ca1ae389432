#pragma once
// An isotropic point light: a Dirac delta in position, so only light sampling reaches it.
#include <cmath>
#include <cstdint>
#include <optional>

#include "renderer/lights/light_bounds.h"
#include "renderer/lights/light_sample.h"

namespace rayfarm {

class DeltaPointLight {
 public:
  /// sample() reads none of its numbers (LightSet::reads_numbers()).
  static constexpr bool kReadsNumbers = false;
  /// The light of point light `index`; nullopt when it emits no power.
  static std::optional<DeltaPointLight> make(const Scene& scene, uint32_t index) {
    const PointLight& pl = scene.point_lights[index];
    const double power = 4.0 * kPi * double(luminance(pl.intensity));
    if (!(power > 0.0)) return std::nullopt;
    return DeltaPointLight(pl, power);
  }

  double power() const { return power_; }
  /// Where the light tree finds it: a point that emits every way.
  LightBounds bounds() const {
    LightBounds b;
    b.lo = b.hi = position_;
    b.cos_o = -1.f;
    b.cos_e = 0.f;
    b.intensity = power_ / (4.0 * kPi);
    return b;
  }

  /// The light as seen from `ref`; pdf is the selection probability p_select. Small: inlined
  /// into the path loop, which GCC otherwise calls it from.
  [[gnu::always_inline]] bool sample(const Vec3& ref, float p_select, float /*u1*/, float /*u2*/,
                                     LightSample& out) const {
    const Vec3 d = position_ - ref;
    const float dist2 = dot(d, d);
    if (!(dist2 > 0.f)) return false;
    out.wi = d / std::sqrt(dist2);
    out.radiance = intensity_ / dist2;
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
  DeltaPointLight(const PointLight& pl, double power)
      : position_(pl.position), intensity_(pl.intensity), power_(power) {}

  Vec3 position_, intensity_;
  double power_ = 0.0;
};

}  // namespace rayfarm
