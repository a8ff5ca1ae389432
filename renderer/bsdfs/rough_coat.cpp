#include "renderer/bsdfs/rough_coat.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include <tbb/parallel_for.h>

#include "renderer/bsdfs/dielectric.h"
#include "renderer/bsdfs/gauss_legendre.h"
#include "renderer/bsdfs/microfacet_distribution.h"

namespace rayfarm {
namespace {

/// The integral of g(wm) over the normals visible from wi (density visible_pdf): a tensor
/// Gauss-Legendre rule on the square that sample_visible maps onto them, which turns the
/// integral into one of a bounded function over [0, 1]^2.
template <int N, class G>
double over_visible_normals(const MicrofacetDistribution& facets, const Vec3& wi, G g) {
  static const GaussLegendre<N> rule;
  double sum = 0.0;
  for (int i = 0; i < N; ++i) {
    double row = 0.0;
    for (int j = 0; j < N; ++j) {
      const Vec3 wm = facets.sample_visible(wi, float(rule.x[i]), float(rule.x[j]));
      row += rule.w[j] * g(wm);
    }
    sum += rule.w[i] * row;
  }
  return sum;
}

/// Light from outside at cosine mu, in the xz plane: the tables need isotropic roughness only.
Vec3 incident(float mu) { return Vec3{std::sqrt(std::max(0.f, 1.f - mu * mu)), 0.f, mu}; }

/// Cosine i of the table: the grid's end at grazing is raised off 0, where wi would lie in
/// the surface and see no facet.
float table_cosine(int i) {
  return std::max(1e-6f, float(i) / float(RoughCoatTable::kCosines - 1));
}

}  // namespace

namespace {

/// The integrand of the transmittance at wm, for light along wi at index ratio eta.
double transmitted(const MicrofacetDistribution& facets, const Vec3& wi, float eta,
                   const Vec3& wm) {
  const float c = dot(wi, wm);
  if (!(c > 0.f)) return 0.0;
  float cos_t = 0.f;
  const float f = fresnel_dielectric(c, eta, cos_t);
  if (f >= 1.f) return 0.0;  // total internal reflection
  // Snell about the micro-normal, wt = (-wi + (c - eta cos_t) wm) / eta, taken without the
  // factor 1 / eta and in double: indices from 1e-30 to 1e30 would overflow it or its length.
  const double k = double(c) - double(eta) * cos_t;
  const double x = k * wm.x - wi.x, y = k * wm.y - wi.y, z = k * wm.z - wi.z;
  const double len = std::sqrt(x * x + y * y + z * z);
  if (!(len > 0.0) || !std::isfinite(len)) return 0.0;
  const Vec3 wt{float(x / len), float(y / len), float(z / len)};
  if (!(wt.z < 0.f)) return 0.0;  // refracted back out: the facets shadow it
  return double(1.f - f) * facets.g1(wt);
}

/// The integrand of the reflectance at wm.
double reflected(const MicrofacetDistribution& facets, const Vec3& wi, float eta, const Vec3& wm) {
  const float c = dot(wi, wm);
  if (!(c > 0.f)) return 0.0;
  const Vec3 wr = reflect_about(wi, wm);
  if (!(wr.z > 0.f)) return 0.0;
  float cos_t = 0.f;
  return double(fresnel_dielectric(c, eta, cos_t)) * facets.g1(wr);
}

/// A textured table's T (index ior) and R from inside (1 / ior) at one cosine, from one set of
/// visible normals: both integrals have the same weight, and the sampler is the costly part.
void transmitted_and_reflected_inside(MicrofacetType type, float alpha, float ior, float mu,
                                      float& t, float& r_inside) {
  static const GaussLegendre<32> rule;
  const MicrofacetDistribution facets(type, alpha, alpha);
  const Vec3 wi = incident(mu);
  double st = 0.0, sr = 0.0;
  for (int i = 0; i < 32; ++i) {
    double rt = 0.0, rr = 0.0;
    for (int j = 0; j < 32; ++j) {
      const Vec3 wm = facets.sample_visible(wi, float(rule.x[i]), float(rule.x[j]));
      rt += rule.w[j] * transmitted(facets, wi, ior, wm);
      rr += rule.w[j] * reflected(facets, wi, 1.f / ior, wm);
    }
    st += rule.w[i] * rt;
    sr += rule.w[i] * rr;
  }
  t = float(st);
  r_inside = float(sr);
}

}  // namespace

float rough_interface_transmittance(MicrofacetType type, float alpha, float eta, float mu) {
  const MicrofacetDistribution facets(type, alpha, alpha);
  const Vec3 wi = incident(mu);
  const auto g = [&](const Vec3& wm) { return transmitted(facets, wi, eta, wm); };
  return float(eta > 1.f ? over_visible_normals<32>(facets, wi, g)
                         : over_visible_normals<128>(facets, wi, g));
}

float rough_interface_reflectance(MicrofacetType type, float alpha, float eta, float mu) {
  const MicrofacetDistribution facets(type, alpha, alpha);
  const Vec3 wi = incident(mu);
  const auto g = [&](const Vec3& wm) { return reflected(facets, wi, eta, wm); };
  return float(eta > 1.f ? over_visible_normals<32>(facets, wi, g)
                         : over_visible_normals<128>(facets, wi, g));
}

RoughCoatTable::RoughCoatTable(float ior, MicrofacetType type, float alpha, bool textured)
    : ior_(ior), type_(type), alpha_(alpha), textured_(textured) {
  const int rows = textured ? kRoughnesses : 1;
  const size_t entries = size_t(rows) * kCosines;
  transmittance_.resize(entries);
  internal_.resize(size_t(rows));
  std::vector<float> reflected_inside(entries);
  // Entries are independent, and a Beckmann table costs a second of one core: in parallel, each
  // written by one task, so the table is the same whatever the threads.
  tbb::parallel_for(size_t{0}, entries, [&](size_t e) {
    const int r = int(e / kCosines), i = int(e % kCosines);
    const float a = textured ? row_roughness(r) : alpha, mu = table_cosine(i);
    // A textured table's rows take the coarser rule for R from inside: averaged over mu into
    // Ri, its errors at the critical angle stay below 1e-3, at a sixteenth of the cost.
    if (textured) {
      transmitted_and_reflected_inside(type, a, ior, mu, transmittance_[e], reflected_inside[e]);
    } else {
      transmittance_[e] = rough_interface_transmittance(type, a, ior, mu);
      reflected_inside[e] = rough_interface_reflectance(type, a, 1.f / ior, mu);
    }
  });
  // The base's diffuse light meets the coating from inside at every cosine, weighted by the
  // cosine: Ri is 2 x the mean over the grid of R(mu) mu, a plain average as the grid is even.
  for (int r = 0; r < rows; ++r) {
    double inside = 0.0;
    for (int i = 0; i < kCosines; ++i)
      inside += double(reflected_inside[size_t(r) * kCosines + i]) * table_cosine(i);
    internal_[size_t(r)] = float(2.0 * inside / kCosines);
  }
}

float RoughCoatTable::row_roughness(int row) {
  const double s = double(row) / double(kRoughnesses - 1);
  return float(s * s * s);
}

RoughCoatTable::Coat RoughCoatTable::at(float alpha) const {
  Coat c;
  if (!textured_) {
    c.row0 = c.row1 = transmittance_.data();
    c.internal = internal_[0];
    return c;
  }
  const float x = std::cbrt(std::clamp(alpha, 0.f, 1.f)) * float(kRoughnesses - 1);
  int i = int(x);
  if (i > kRoughnesses - 2) i = kRoughnesses - 2;
  c.weight = x - float(i);
  c.row0 = transmittance_.data() + size_t(i) * kCosines;
  c.row1 = c.row0 + kCosines;
  c.internal = internal_[size_t(i)] + (internal_[size_t(i) + 1] - internal_[size_t(i)]) * c.weight;
  return c;
}

const RoughCoatTable& unprepared_rough_coat(float ior, MicrofacetType type, float alpha) {
  thread_local std::vector<std::unique_ptr<RoughCoatTable>> made;
  for (const auto& t : made) {
    if (t->ior() == ior && t->type() == type && t->alpha() == alpha) return *t;
  }
  made.push_back(std::make_unique<RoughCoatTable>(ior, type, alpha, false));
  return *made.back();
}

}  // namespace rayfarm
