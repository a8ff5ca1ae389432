#pragma once
// Where a time within the shutter falls among the poses of moving geometry (common/scene/
// motion.h): between pose i and i + 1, a fraction f of the way, as Embree moves vertices,
// spheres and placements (linearly between evenly spaced poses from time 0 to 1).
#include <algorithm>
#include <cstdint>

#include "common/math/vec3.h"

namespace rayfarm {

struct PoseBlend {
  uint32_t i;  ///< the pose before the time
  float f;     ///< the fraction of the way to pose i + 1
};

/// `time` in [0, 1] among `poses` (at least 2) poses.
inline PoseBlend pose_blend(uint32_t poses, float time) {
  const float at = std::clamp(time, 0.f, 1.f) * static_cast<float>(poses - 1);
  const uint32_t i = std::min(static_cast<uint32_t>(at), poses - 2);
  return {i, at - static_cast<float>(i)};
}

inline Vec3 blend(const Vec3& a, const Vec3& b, float f) { return a * (1.f - f) + b * f; }
inline float blend(float a, float b, float f) { return a * (1.f - f) + b * f; }

}  // namespace rayfarm
