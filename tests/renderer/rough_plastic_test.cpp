// The rough plastic's coating (renderer/bsdfs/rough_coat.h): what it lets through to the base, T(mu),
// and what it reflects back inside, Ri, against an independent integration over the micro-normals;
// the tables a textured roughness reads against direct computation; and the white furnace.
// Sampling, pdf, reciprocity and chi-square of rough plastic, with both distributions, are the
// generic tests of microfacet_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>

#include "common/scene/scene.h"
#include "tests/renderer/bsdf_test_support.h"
#include "renderer/bsdfs/bsdf.h"
#include "renderer/bsdfs/dielectric.h"
#include "renderer/bsdfs/microfacet_distribution.h"
#include "renderer/bsdfs/rough_coat.h"

namespace rayfarm {
namespace {

using testing::AngleGrid;
using testing::for_each_node;
using testing::kTwoPi;

constexpr MicrofacetType kTypes[] = {MicrofacetType::kGgx, MicrofacetType::kBeckmann};

const char* type_name(MicrofacetType t) { return t == MicrofacetType::kGgx ? "ggx" : "beckmann"; }

/// The integral over the micro-normals of g(wm) weighted by the normals visible from wi,
/// D(wm) G1(wi) max(0, wi.wm) / wi.z, computed without the visible-normal sampler the tables use:
/// the midpoint rule over the projected normals' own parametrisation (u -> tan^2 theta with
/// density D cos theta: GGX a^2 u / (1 - u), Beckmann -a^2 ln(1 - u); phi uniform), symmetric in
/// phi about wi's plane. The visible normals' weight 1 / cos theta grows like 1 / sqrt(1 - u)
/// towards grazing normals, which the substitution u = 1 - v^2 (du = 2 v dv) makes bounded.
template <class G>
double over_normals(MicrofacetType type, float alpha, const Vec3& wi, G g) {
  const MicrofacetDistribution facets(type, alpha, alpha);
  constexpr int kU = 1200, kPhi = 300;
  const double g1 = facets.g1(wi), a2 = double(alpha) * alpha;
  double sum = 0.0;
  for (int i = 0; i < kU; ++i) {
    const double v = (i + 0.5) / kU, u = 1.0 - v * v;
    const double t2 = type == MicrofacetType::kGgx ? a2 * u / (1.0 - u) : -a2 * std::log(1.0 - u);
    const double cos_m = 1.0 / std::sqrt(1.0 + t2), sin_m = std::sqrt(t2) * cos_m;
    for (int j = 0; j < kPhi; ++j) {
      const double phi = (j + 0.5) / kPhi * 0.5 * kTwoPi;  // [0, pi], doubled by symmetry
      const Vec3 wm{float(sin_m * std::cos(phi)), float(sin_m * std::sin(phi)), float(cos_m)};
      const double c = dot(wi, wm);
      if (c <= 0.0) continue;
      sum += 2.0 * v * g(wm, c) * g1 * c / (wi.z * cos_m);
    }
  }
  return sum / (double(kU) * kPhi);
}

Vec3 incident(float mu) { return Vec3{std::sqrt(1.f - mu * mu), 0.f, mu}; }

double transmittance_reference(MicrofacetType type, float alpha, float eta, float mu) {
  const MicrofacetDistribution facets(type, alpha, alpha);
  const Vec3 wi = incident(mu);
  return over_normals(type, alpha, wi, [&](const Vec3& wm, double c) {
    float cos_t = 0.f;
    const double f = fresnel_dielectric(float(c), eta, cos_t);
    if (f >= 1.0) return 0.0;
    // The refracted direction: -wi / eta + (c / eta - cos_t) wm.
    const Vec3 wt = normalize(wm * float(c / eta - cos_t) - wi * (1.f / eta));
    return wt.z < 0.f ? (1.0 - f) * facets.g1(wt) : 0.0;
  });
}

double reflectance_reference(MicrofacetType type, float alpha, float eta, float mu) {
  const MicrofacetDistribution facets(type, alpha, alpha);
  const Vec3 wi = incident(mu);
  return over_normals(type, alpha, wi, [&](const Vec3& wm, double c) {
    const Vec3 wr = reflect_about(wi, wm);
    float cos_t = 0.f;
    return wr.z > 0.f ? fresnel_dielectric(float(c), eta, cos_t) * facets.g1(wr) : 0.0;
  });
}

TEST(RoughCoatTest, TransmittanceAndReflectanceMatchAnIndependentIntegration) {
  // The Gauss-Legendre rule over the sampler's square against the midpoint rule over the
  // normals (1200 x 300 nodes): they agree to 1.1e-4 for T; inside (eta 1 / 1.5) total internal
  // reflection makes the integrand jump, and they agree to 4e-4.
  double worst_t = 0.0, worst_r = 0.0;
  for (const MicrofacetType type : kTypes)
    for (const float alpha : {0.1f, 0.4f, 1.f})
      for (const float mu : {0.05f, 0.3f, 0.7f, 1.f}) {
        const double t = rough_interface_transmittance(type, alpha, 1.5f, mu);
        const double t_ref = transmittance_reference(type, alpha, 1.5f, mu);
        EXPECT_NEAR(t, t_ref, 5e-4) << type_name(type) << " alpha " << alpha << " mu " << mu;
        const double r = rough_interface_reflectance(type, alpha, 1.f / 1.5f, mu);
        const double r_ref = reflectance_reference(type, alpha, 1.f / 1.5f, mu);
        EXPECT_NEAR(r, r_ref, 1e-3) << type_name(type) << " alpha " << alpha << " mu " << mu;
        worst_t = std::max(worst_t, std::fabs(t - t_ref));
        worst_r = std::max(worst_r, std::fabs(r - r_ref));
        // What one scattering does not transmit it reflects or loses between the facets.
        EXPECT_LE(t + rough_interface_reflectance(type, alpha, 1.5f, mu), 1.0 + 1e-4);
      }
  std::cout << "T: max |table rule - reference| " << worst_t << "; R inside: " << worst_r << "\n";
}

TEST(RoughCoatTest, TexturedTableInterpolatesWithinAThousandth) {
  // A textured roughness reads T between rows of cbrt(alpha): at the midpoints between rows,
  // where linear interpolation errs most, against T computed there, at the table's cosines
  // (every third: measured 3.0e-4 GGX, 3.6e-4 Beckmann) and between them (where the cosine's own
  // interpolation adds its error, as for a constant roughness); Ri at some midpoints against the
  // constant-roughness table's (at every tenth midpoint: up to 5.8e-4 GGX, 2.8e-4 Beckmann).
  for (const MicrofacetType type : kTypes) {
    const float ior = 1.5f;
    const RoughCoatTable table(ior, type, 0.f, true);
    double worst_nodes = 0.0, worst_between = 0.0, worst_ri = 0.0;
    constexpr int n = RoughCoatTable::kCosines;
    for (int j = 0; j + 1 < RoughCoatTable::kRoughnesses; ++j) {
      const float s = (j + 0.5f) / float(RoughCoatTable::kRoughnesses - 1), alpha = s * s * s;
      const RoughCoatTable::Coat coat = table.at(alpha);
      for (int i = 0; i < n; i += 3) {
        const float mu = std::max(1e-6f, float(i) / float(n - 1));
        const double direct = rough_interface_transmittance(type, alpha, ior, mu);
        worst_nodes = std::max(worst_nodes, std::fabs(coat.transmittance(mu) - direct));
        const float mid = (float(i) + 0.5f) / float(n - 1);
        if (mid < 0.05f || i + 1 >= n) continue;
        const double direct_mid = rough_interface_transmittance(type, alpha, ior, mid);
        worst_between = std::max(worst_between, std::fabs(coat.transmittance(mid) - direct_mid));
      }
      if (j % 31 == 0 || j == RoughCoatTable::kRoughnesses - 2) {
        const float ri = RoughCoatTable(ior, type, alpha, false).at(alpha).internal;
        worst_ri = std::max(worst_ri, double(std::fabs(coat.internal - ri)));
      }
    }
    std::cout << type_name(type) << ": textured table, max |T - direct| " << worst_nodes
              << " at the cosines, " << worst_between << " between them (mu >= 0.05); max |Ri - "
              << "direct| " << worst_ri << "\n";
    EXPECT_LT(worst_nodes, 1e-3) << type_name(type);
    // Between the cosines the table's grid of 64 adds its linear interpolation's error (that of
    // a constant roughness too): up to 1.02e-3 near mu 0.05 for GGX.
    EXPECT_LT(worst_between, 1.5e-3) << type_name(type);
    EXPECT_LT(worst_ri, 1e-3) << type_name(type);
  }
}

/// Integral of eval(wo, .) over the upper hemisphere (the plastic reflects only), channel 0.
double albedo(const Bsdf& bsdf, const Vec3& wo, double step) {
  AngleGrid grid;
  double sum = 0.0;
  for_each_node(grid, step, [&](int, const Vec3& wi, double w) { sum += w * bsdf.eval(wo, wi).x; });
  return sum;
}

Material plastic(const Vec3& rho, float alpha, MicrofacetType type, bool nonlinear = false) {
  PlasticMaterial p;
  p.diffuse_reflectance = rho;
  p.alpha = alpha;
  p.distribution = type;
  p.nonlinear = nonlinear;
  Material m;
  m.kind = p;
  return m;
}

TEST(RoughPlasticTest, CoatLobeReflectsTheTablesRAndLetsThroughTheRest) {
  // Over a black base the plastic is its coat's specular lobe alone: its albedo, integrated
  // over directions, is R(mu) of the coat's tables, and T(mu) is at most what it leaves,
  // 1 - R(mu), short by what one scattering loses between the facets.
  const float ior = PlasticMaterial{}.ior;
  double worst = 0.0, most_lost = 0.0;
  for (const MicrofacetType type : kTypes)
    for (const float alpha : {0.1f, 0.4f, 1.f}) {
      const Bsdf black(plastic(Vec3(0.f), alpha, type));
      for (const float mu : {0.2f, 0.5f, 0.9f}) {
        const Vec3 wo{std::sqrt(1.f - mu * mu), 0.f, mu};
        const double e_spec = albedo(black, wo, std::min(0.02, alpha / 10.0));
        const double r = rough_interface_reflectance(type, alpha, ior, mu);
        const double t = rough_interface_transmittance(type, alpha, ior, mu);
        EXPECT_NEAR(e_spec, r, 1e-3) << type_name(type) << " alpha " << alpha << " mu " << mu;
        EXPECT_LE(t, 1.0 - e_spec + 1e-3) << type_name(type) << " alpha " << alpha << " mu " << mu;
        worst = std::max(worst, std::fabs(e_spec - r));
        most_lost = std::max(most_lost, 1.0 - e_spec - t);
      }
    }
  std::cout << "coat lobe's albedo against R: max difference " << worst
            << "; most lost between the facets 1 - R - T = " << most_lost << "\n";
}

TEST(RoughPlasticTest, WhiteFurnace) {
  // A white base (rho 1, linear) under a rough coat reflects at most what it receives. It
  // returns less than all of it, by what single scattering loses in the coat: light the facets
  // neither reflect nor refract on the way in, on the way out, and at every inner bounce (Ri is
  // the rough interface's reflectance from inside, smaller than 1 - (1 - average T) / eta^2).
  // Measured at normal incidence: alpha 0.1 returns 0.910 (GGX) and 0.968 (Beckmann), alpha 1
  // 0.340 and 0.511: the loss grows with alpha.
  for (const MicrofacetType type : kTypes)
    for (const float mu : {0.1f, 0.5f, 1.f}) {
      const Vec3 wo{std::sqrt(1.f - mu * mu), 0.f, mu};
      double previous = 1.0;
      for (const float alpha : {0.1f, 0.4f, 1.f}) {
        const Bsdf white(plastic(Vec3(1.f), alpha, type));
        const double a = albedo(white, wo, std::min(0.02, alpha / 10.0));
        std::cout << type_name(type) << " alpha " << alpha << " mu " << mu << ": albedo " << a
                  << "\n";
        EXPECT_LE(a, 1.0 + 1e-3) << type_name(type) << " alpha " << alpha << " mu " << mu;
        EXPECT_LT(a, previous) << type_name(type) << " alpha " << alpha << " mu " << mu;
        previous = a;
      }
    }
}

}  // namespace
}  // namespace rayfarm
