#include "renderer/bsdfs/microfacet.h"

#include <algorithm>
#include <cmath>
#include <complex>

namespace rayfarm {

GgxDistribution::GgxDistribution(float alpha_u, float alpha_v)
    : ax_(std::max(alpha_u, kSmoothAlpha)),
      ay_(std::max(alpha_v, kSmoothAlpha)),
      smooth_(alpha_u < kSmoothAlpha && alpha_v < kSmoothAlpha) {}

float GgxDistribution::d(const Vec3& wm) const {
  if (wm.z <= 0.f) return 0.f;
  // cos^4 (1 + tan^2 (cos^2 phi / ax^2 + sin^2 phi / ay^2))^2 written as one sum of squares, so
  // that nothing divides by cos at grazing micro-normals.
  const float x = wm.x / ax_, y = wm.y / ay_;
  const float t = x * x + y * y + wm.z * wm.z;
  return 1.f / (kPi * ax_ * ay_ * t * t);
}

float GgxDistribution::lambda(const Vec3& w) const {
  const float z2 = w.z * w.z;
  const float s = (ax_ * w.x) * (ax_ * w.x) + (ay_ * w.y) * (ay_ * w.y);  // alpha^2 sin^2
  if (z2 == 0.f) return s > 0.f ? INFINITY : 0.f;
  const float a2t2 = s / z2;
  // (sqrt(1 + a2t2) - 1) / 2 without the cancellation for small a2t2.
  return a2t2 / (2.f * (std::sqrt(1.f + a2t2) + 1.f));
}

float GgxDistribution::visible_pdf(const Vec3& w, const Vec3& wm) const {
  const float c = dot(w, wm);
  if (c <= 0.f || w.z <= 0.f) return 0.f;
  return g1(w) * c * d(wm) / w.z;
}

Vec3 GgxDistribution::sample_visible(const Vec3& w, float u1, float u2) const {
  // Stretch to the hemisphere configuration (alpha 1), sample the projected disk of the
  // hemisphere seen from there, and unstretch.
  const Vec3 vh = normalize(Vec3{ax_ * w.x, ay_ * w.y, w.z});
  const float len2 = vh.x * vh.x + vh.y * vh.y;
  const Vec3 t1 = len2 > 0.f ? Vec3{-vh.y, vh.x, 0.f} / std::sqrt(len2) : Vec3{1.f, 0.f, 0.f};
  const Vec3 t2 = cross(vh, t1);
  const float r = std::sqrt(u1), phi = 2.f * kPi * u2;
  const float p1 = r * std::cos(phi);
  float p2 = r * std::sin(phi);
  const float s = 0.5f * (1.f + vh.z);
  p2 = (1.f - s) * std::sqrt(std::max(0.f, 1.f - p1 * p1)) + s * p2;
  const Vec3 nh = t1 * p1 + t2 * p2 + vh * std::sqrt(std::max(0.f, 1.f - p1 * p1 - p2 * p2));
  return normalize(Vec3{ax_ * nh.x, ay_ * nh.y, std::max(1e-6f, nh.z)});
}

float fresnel_conductor(float cos_i, float eta, float k) {
  // The Fresnel equations with a complex transmitted cosine, in double: eta and k of metals
  // reach 10 and their squares cancel against each other.
  using C = std::complex<double>;
  const double ci = std::clamp(double(cos_i), 0.0, 1.0);
  const C n(eta, k);
  const C cos_t = std::sqrt(1.0 - (1.0 - ci * ci) / (n * n));
  const C r_perp = (ci - n * cos_t) / (ci + n * cos_t);
  const C r_parl = (n * ci - cos_t) / (n * ci + cos_t);
  return static_cast<float>(0.5 * (std::norm(r_perp) + std::norm(r_parl)));
}

Vec3 fresnel_conductor(float cos_i, const Vec3& eta, const Vec3& k) {
  return {fresnel_conductor(cos_i, eta.x, k.x), fresnel_conductor(cos_i, eta.y, k.y),
          fresnel_conductor(cos_i, eta.z, k.z)};
}

Vec3 fresnel_schlick(const Vec3& f0, float cos_i) {
  const float m = std::clamp(1.f - cos_i, 0.f, 1.f);
  const float m5 = (m * m) * (m * m) * m;
  return f0 + (Vec3(1.f) - f0) * m5;
}

}  // namespace rayfarm
