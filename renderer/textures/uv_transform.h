#pragma once
// The UV transform of a texture, in glTF's KHR_texture_transform convention: scale, then rotate,
// then offset, applied to the surface's (u, v) before the lookup. docs/textures.md.
#include <array>
#include <cmath>

#include "common/image/texture_options.h"

namespace rayfarm {

/// A UvTransform as the affine map it is, computed once (lookups only multiply and add).
class UvMap {
 public:
  UvMap() = default;
  explicit UvMap(const UvTransform& t) {
    if (t.matrix) {
      for (int i = 0; i < 6; ++i) m_[i] = (*t.matrix)[i];
      return;
    }
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
