#include "worker/bsdfs/bsdf_sample.h"

#include <algorithm>
#include <cmath>

namespace rayfarm {

Vec3 sample_cosine_hemisphere(float u1, float u2) {
  // Concentric disk mapping (Shirley-Chiu), then lift to the hemisphere.
  const float a = 2.f * u1 - 1.f, b = 2.f * u2 - 1.f;
  float r = 0.f, phi = 0.f;
  if (a == 0.f && b == 0.f) return {0.f, 0.f, 1.f};
  if (std::fabs(a) > std::fabs(b)) {
    r = a;
    phi = (kPi / 4.f) * (b / a);
  } else {
    r = b;
    phi = (kPi / 2.f) - (kPi / 4.f) * (a / b);
  }
  const float x = r * std::cos(phi), y = r * std::sin(phi);
  return {x, y, std::sqrt(std::max(0.f, 1.f - x * x - y * y))};
}

}  // namespace rayfarm
