#include "renderer/bsdfs/beckmann.h"

#include <algorithm>
#include <cmath>

#include "renderer/bsdfs/microfacet.h"

namespace rayfarm {
namespace {

constexpr double kSqrtPi = 1.7724538509055160273;

/// Slopes beyond this many (unit-roughness) units carry less than exp(-81) of the density: the
/// inversion's bracket.
constexpr double kSlopeBound = 9.0;

/// A start for the inversion: erfinv(t) within a few per mille (a closed form fitted to the
/// inverse error function's asymptotics), clamped to a finite value at t = +-1.
double approximate_erfinv(double t) {
  t = std::clamp(t, -1.0 + 1e-15, 1.0 - 1e-15);
  constexpr double kA = 0.147;
  const double ln = std::log((1.0 - t) * (1.0 + t));
  const double b = 2.0 / (3.141592653589793 * kA) + 0.5 * ln;
  return std::copysign(std::sqrt(std::sqrt(b * b - ln / kA) - b), t);
}

}  // namespace

double beckmann_visible_slope(double cos_theta, double sin_theta, double u) {
  // The unnormalised distribution function of x, from the left:
  //   K(x) = cos erfc(-x) / 2 + sin exp(-x^2) / (2 sqrt(pi)),
  // which rises to its total at x = cos / sin, where the facets turn their backs on the viewer.
  // erfc(-x) keeps the left tail's digits that 1 + erf(x) would cancel.
  u = std::clamp(u, 0.0, 1.0);
  double lo = -kSlopeBound;
  double hi = sin_theta > cos_theta / kSlopeBound ? cos_theta / sin_theta : kSlopeBound;
  const double target =
      u * 0.5 * (cos_theta * std::erfc(-hi) + sin_theta * std::exp(-hi * hi) / kSqrtPi);
  // The start blends the two limits: a normal law at normal incidence (x = erfinv(2u - 1)) and
  // K proportional to exp(-x^2) at grazing incidence (x = -sqrt(-ln u)); it halves the
  // iterations towards grazing incidence.
  const double grazing = sin_theta > 0.0 ? -std::sqrt(-std::log(std::max(u, 1e-300))) : 0.0;
  double x =
      std::clamp(cos_theta * approximate_erfinv(2.0 * u - 1.0) + sin_theta * grazing, lo, hi);
  // Newton's method, falling back to bisection whenever a step leaves the bracket: K is
  // increasing, so the bracket always holds the root and the iteration cannot diverge. A Newton
  // step below 1e-7 leaves an error of the order of its square.
  for (int i = 0; i < 100; ++i) {
    const double e = std::exp(-x * x);
    const double f = 0.5 * (cos_theta * std::erfc(-x) + sin_theta * e / kSqrtPi) - target;
    if (f == 0.0) break;
    (f > 0.0 ? hi : lo) = x;
    const double density = (cos_theta - sin_theta * x) * e / kSqrtPi;
    const double next = density > 0.0 ? x - f / density : lo;
    if (next > lo && next < hi) {
      const bool converged = std::fabs(next - x) < 1e-7 * std::max(1.0, std::fabs(x));
      x = next;
      if (converged) break;
    } else {
      x = 0.5 * (lo + hi);
      if (hi - lo < 1e-12) break;
    }
  }
  return x;
}

BeckmannDistribution::BeckmannDistribution(float alpha_u, float alpha_v)
    : ax_(std::max(alpha_u, kSmoothAlpha)),
      ay_(std::max(alpha_v, kSmoothAlpha)),
      smooth_(alpha_u < kSmoothAlpha && alpha_v < kSmoothAlpha) {}

float BeckmannDistribution::d(const Vec3& wm) const {
  if (wm.z <= 0.f) return 0.f;
  // exp(-tan^2 (cos^2 phi / ax^2 + sin^2 phi / ay^2)) / (pi ax ay cos^4). The exponential
  // vanishes long before cos^4 does, which keeps grazing micro-normals from 0 / 0.
  const float z2 = wm.z * wm.z;
  const float x = wm.x / ax_, y = wm.y / ay_;
  const float e = std::exp(-(x * x + y * y) / z2);
  return e > 0.f ? e / (kPi * ax_ * ay_ * z2 * z2) : 0.f;
}

float BeckmannDistribution::lambda(const Vec3& w) const {
  const float s2 = (ax_ * w.x) * (ax_ * w.x) + (ay_ * w.y) * (ay_ * w.y);  // alpha^2 sin^2
  if (s2 == 0.f) return 0.f;
  const float z = std::fabs(w.z);
  if (z == 0.f) return INFINITY;
  // a = 1 / (alpha tan); Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)), with erfc for
  // erf - 1: beyond a = 4 both terms are below 1e-8 and nearly cancel, so the result is clamped
  // to its true sign.
  const float a = z / std::sqrt(s2);
  const float l = 0.5f * (std::exp(-a * a) / (a * float(kSqrtPi)) - std::erfc(a));
  return std::max(0.f, l);
}

float BeckmannDistribution::visible_pdf(const Vec3& w, const Vec3& wm) const {
  const float c = dot(w, wm);
  if (c <= 0.f || w.z <= 0.f) return 0.f;
  return g1(w) * c * d(wm) / w.z;
}

Vec3 BeckmannDistribution::sample_visible(const Vec3& w, float u1, float u2) const {
  // Stretch to unit roughness (the slope distribution is then isotropic), draw the slopes
  // visible from there in the plane of incidence (x) and across it (y, independent: a normal
  // law), rotate them to the direction's azimuth, and unstretch.
  const double sx = double(ax_) * w.x, sy = double(ay_) * w.y, sz = w.z;
  const double len = std::sqrt(sx * sx + sy * sy + sz * sz);
  const double r = std::sqrt(sx * sx + sy * sy);
  const double cos_t = sz / len, sin_t = r / len;
  const double cos_p = r > 0.0 ? sx / r : 1.0, sin_p = r > 0.0 ? sy / r : 0.0;
  const double along = beckmann_visible_slope(cos_t, sin_t, u1);
  const double across = beckmann_visible_slope(1.0, 0.0, u2);
  const double slope_x = ax_ * (cos_p * along - sin_p * across);
  const double slope_y = ay_ * (sin_p * along + cos_p * across);
  // The micro-normal of slopes (sx, sy) is (-sx, -sy, 1) normalised.
  const double n = std::sqrt(slope_x * slope_x + slope_y * slope_y + 1.0);
  return Vec3{float(-slope_x / n), float(-slope_y / n), float(1.0 / n)};
}

}  // namespace rayfarm
