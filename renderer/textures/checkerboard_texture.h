#pragma once
// A procedural checkerboard, defined as Mitsuba 3's `checkerboard` texture is, so that scenes
// from it look the same: with (u', v') the transformed UVs, colour0 where exactly one of
// frac(u') > 1/2 and frac(v') > 1/2 holds, colour1 elsewhere (so colour1 at the origin's square).
// One period (two squares per axis) spans one unit of UV.
#include <cmath>

#include "common/math/vec4.h"
#include "renderer/textures/uv_transform.h"

namespace rayfarm {

class CheckerboardTexture {
 public:
  CheckerboardTexture(const Vec4& colour0, const Vec4& colour1, const UvTransform& transform = {})
      : colour0_(colour0), colour1_(colour1), map_(transform) {}

  Vec4 eval(float u, float v) const {
    const auto [tu, tv] = map_.apply(u, v);
    const bool upper_u = tu - std::floor(tu) > 0.5, upper_v = tv - std::floor(tv) > 0.5;
    return upper_u != upper_v ? colour0_ : colour1_;
  }
  float eval_channel(float u, float v, int channel) const { return eval(u, v)[channel]; }
  /// The average over the plane: both colours cover half of it.
  Vec4 mean() const { return 0.5f * (colour0_ + colour1_); }

 private:
  Vec4 colour0_, colour1_;
  UvMap map_;
};

}  // namespace rayfarm
