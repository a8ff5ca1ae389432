#pragma once
// Material parameters evaluated at one surface point: a constant as it is, a textured one as its
// texture's value there times its factor. Built per path vertex; a scene without textures never
// makes one with a set, and its parameters cost one branch each.
#include <algorithm>
#include <cassert>

#include "common/math/vec2.h"
#include "common/scene/textures.h"
#include "renderer/textures/texture_set.h"

namespace rayfarm {

class TextureLookup {
 public:
  /// For constant parameters only.
  TextureLookup() = default;
  TextureLookup(const TextureSet* set, Vec2 uv) : set_(set), uv_(uv) {}
  /// With a vertex colour that multiplies every reflectance (Material::vertex_colours).
  TextureLookup(const TextureSet* set, Vec2 uv, const Vec3& tint)
      : set_(set), uv_(uv), tint_(tint), tinted_(true) {}
  /// Whether this lookup reads textures (else every parameter must be a constant).
  bool has_textures() const { return set_ != nullptr; }

  /// A reflectance: the texture's RGB clamped to [0, 1], times the factor (and the tint).
  Vec3 reflectance(const TexturedRgb& p) const {
    Vec3 out = p.value;
    if (p.texture >= 0) {
      const Vec4 t = lookup(p.texture);
      out = out * Vec3(clamp01(t[0]), clamp01(t[1]), clamp01(t[2]));
    }
    return tinted_ ? out * tint_ : out;
  }
  /// A radiance: the texture's RGB, unbounded above (negative and NaN texels read 0), times the
  /// factor.
  Vec3 radiance(const TexturedRgb& p) const {
    if (p.texture < 0) return p.value;
    const Vec4 t = lookup(p.texture);
    const auto positive = [](float v) { return v > 0.f ? v : 0.f; };
    return p.value * Vec3(positive(t[0]), positive(t[1]), positive(t[2]));
  }
  /// A number: the chosen channel (or the RGB mean) times the factor; a NaN texel reads 0 (an
  /// infinite one stays infinite, and resolve_textures() keeps it at the top of the range).
  float number(const TexturedFloat& p) const {
    if (p.texture < 0) return p.value;
    const Vec4 t = lookup(p.texture);
    float v = 0.f;
    switch (p.channel) {
      case TextureChannel::kR:
        v = t[0];
        break;
      case TextureChannel::kG:
        v = t[1];
        break;
      case TextureChannel::kB:
        v = t[2];
        break;
      case TextureChannel::kA:
        v = t[3];
        break;
      case TextureChannel::kMean:
        v = (t[0] + t[1] + t[2]) * (1.f / 3.f);
        break;
    }
    const float scaled = v * p.value;
    return std::isnan(scaled) ? 0.f : scaled;
  }

 private:
  static float clamp01(float v) { return v >= 0.f ? std::min(v, 1.f) : 0.f; }  // NaN -> 0
  Vec4 lookup(int32_t texture) const {
    assert(set_ != nullptr && "a textured parameter looked up without textures");
    return set_->eval(static_cast<uint32_t>(texture), uv_.x, uv_.y);
  }

  const TextureSet* set_ = nullptr;
  Vec2 uv_;
  Vec3 tint_{1.f};
  bool tinted_ = false;
};

}  // namespace rayfarm
