#pragma once
// A spot light that projects an image (SpotLight::image: Mitsuba's textured `spot` and its
// `projector`). A point light whose intensity towards a direction is the light's intensity times
// the image at the direction's (u, v), found in the light's own frame (x, y, z with z its axis):
// u = 0.5 + u_scale x / z, v = 0.5 + v_scale y / z.
// - A textured spot keeps the spot's cone and falloff (spot_light.h).
// - A projector lights the image's rectangle (u, v in [0, 1], z > 0) and divides its intensity
//   by cos^3 of the angle to its axis: a plane facing it at distance h then receives the same
//   irradiance everywhere in the rectangle, intensity x image / h^2. Its cone (for the light
//   tree) is the one through the rectangle's corners.
// A Dirac delta in position: only light sampling reaches it. A kind of its own, so that plain
// spot lights carry no trace of images.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "renderer/lights/spot_light.h"
#include "renderer/textures/texture_lookup.h"
#include "renderer/textures/texture_set.h"

namespace rayfarm {

class ImageSpotLight {
 public:
  /// sample() reads none of its numbers (LightSet::reads_numbers()).
  static constexpr bool kReadsNumbers = false;

  /// The light of spot light `index` when it has an image; nullopt otherwise or when it emits
  /// no power.
  static std::optional<ImageSpotLight> make(const Scene& scene, uint32_t index,
                                            const TextureSet* textures) {
    const SpotLight& s = scene.spot_lights[index];
    if (!s.image) return std::nullopt;
    auto cone = DeltaSpotLight::make(scene, index);
    if (!cone) return std::nullopt;
    ImageSpotLight light(*cone, *s.image, textures);
    // The image's mean (a constant's own value): the share of the light's power it lets through.
    Vec3 mean = s.image->image.value;
    if (s.image->image.is_textured() && textures != nullptr) {
      const Vec4 t = textures->mean(static_cast<uint32_t>(s.image->image.texture));
      mean = mean * Vec3(std::max(t.x, 0.f), std::max(t.y, 0.f), std::max(t.z, 0.f));
    }
    const double share = double(luminance(mean));
    // The light tree's intensity: the cone's along its axis, times the image's mean, and for a
    // projector the growth towards its rectangle's corners (1 / cos^3 there).
    double peak = share;
    if (s.image->projector) {
      const double c = std::cos(double(s.cutoff_deg * (kPi / 180.f)));
      peak /= c * c * c;
      // The intensity over the rectangle's solid angle, where 1 / cos^3 cancels the solid angle's
      // cos^3 on the plane z = 1: intensity x image x the rectangle's area there.
      const double area = 1.0 / std::fabs(double(s.image->u_scale) * s.image->v_scale);
      light.power_ = double(luminance(s.intensity)) * share * area;
    } else {
      light.power_ = cone->power() * share;
    }
    light.bounds_scale_ = static_cast<float>(std::max(peak, 1e-6));
    // Any image at all keeps a share of the selection, however dim it reads.
    if (!(light.power_ > 0.0)) light.power_ = cone->power() * 1e-6;
    if (!(light.power_ > 0.0)) return std::nullopt;
    return light;
  }

  double power() const { return power_; }
  /// The spot's cone (a projector's reaches its rectangle's corners), its intensity scaled by
  /// the image.
  LightBounds bounds() const {
    LightBounds b = cone_.bounds();
    b.intensity *= bounds_scale_;
    return b;
  }

  /// The light as seen from `ref`; pdf is the selection probability p_select.
  bool sample(const Vec3& ref, float p_select, float /*u1*/, float /*u2*/, LightSample& out) const {
    const Vec3 d = cone_.position() - ref;
    const float dist2 = dot(d, d);
    if (!(dist2 > 0.f)) return false;
    out.wi = d / std::sqrt(dist2);
    const Vec3 w = -1.f * out.wi;  // from the light towards ref
    const float z = dot(w, cone_.axis());
    if (!(z > 0.f)) return false;
    const Vec2 uv{0.5f + image_.u_scale * dot(w, image_.x_axis) / z,
                  0.5f + image_.v_scale * dot(w, image_.y_axis) / z};
    float factor;
    if (image_.projector) {
      if (!(uv.x >= 0.f && uv.x <= 1.f && uv.y >= 0.f && uv.y <= 1.f)) return false;
      factor = 1.f / (z * z * z);
    } else {
      factor = cone_.falloff(w);
      if (!(factor > 0.f)) return false;
    }
    const Vec3 image = TextureLookup(textures_, uv).radiance(image_.image);
    out.radiance = cone_.intensity() * image * (factor / dist2);
    if (is_black(out.radiance)) return false;
    out.target = cone_.position();
    out.pdf = p_select;
    out.delta = true;
    return true;
  }
  /// No ray hits a point: BSDF sampling never reaches it.
  float pdf(float /*p_select*/, const Vec3& /*ref*/, const Vec3& /*p*/, const Vec3& /*n*/) const {
    return 0.f;
  }

 private:
  ImageSpotLight(const DeltaSpotLight& cone, const SpotImage& image, const TextureSet* textures)
      : cone_(cone), image_(image), textures_(textures) {}

  DeltaSpotLight cone_;
  SpotImage image_;
  const TextureSet* textures_;
  float bounds_scale_ = 1.f;
  double power_ = 0.0;
};

}  // namespace rayfarm
