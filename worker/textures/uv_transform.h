#pragma once
// The UV transform of a texture, in glTF's KHR_texture_transform convention: scale, then rotate,
// then offset, applied to the surface's (u, v) before the lookup. docs/textures.md.
#include <array>
#include <cmath>

namespace rayfarm {

/// What a scene states. `rotation` (radians) turns the UVs counter-clockwise about the origin,
/// which turns the image clockwise: u' = cos r * su u + sin r * sv v + offset_u,
/// v' = -sin r * su u + cos r * sv v + offset_v.
struct UvTransform {
  std::array<float, 2> offset{0.f, 0.f};
  std::array<float, 2> scale{1.f, 1.f};
  float rotation = 0.f;
};

/// A UvTransform as the affine map it is, computed once (lookups only multiply and add).
class UvMap {
 public:
  UvMap() = default;
  explicit UvMap(const UvTransform& t) {
    const double c = std::cos(double{t.rotation}), s = std::sin(double{t.rotation});
    m_ = {c * t.scale[0],  s * t.scale[1], t.offset[0],
          -s * t.scale[0], c * t.scale[1], t.offset[1]};
  }

  std::array<double, 2> apply(double u, double v) const {
    return {m_[0] * u + m_[1] * v + m_[2], m_[3] * u + m_[4] * v + m_[5]};
  }

 private:
  std::array<double, 6> m_{1, 0, 0, 0, 1, 0};
};

}  // namespace rayfarm
