// The Beckmann microfacet distribution (renderer/bsdfs/beckmann.h) against independent closed forms
// and quadratures: D is normalised, Lambda is the exact Smith form and G1 the masking integral,
// the slope inversion hits its distribution function, sample_visible() follows visible_pdf(),
// and the three rough BSDFs built on it sample what their pdf() says at the narrow roughness
// (0.02) that the whole-sphere tests of microfacet_test.cpp cannot resolve cheaply. The rough
// BSDFs' generic checks (sample against pdf and eval, pdf integral, reciprocity, albedo,
// chi-square over the sphere) run on Beckmann cases in microfacet_test.cpp.
//
// Statistics. The file makes at most kHypotheses chi-square tests, held together at significance
// kAlpha = 0.01 by a Bonferroni correction: each must reach a p-value above kAlpha /
// kHypotheses. Expected counts come from deterministic quadratures (bsdf_test_support.h) with
// cells of a tenth of the lobe's narrowest roughness; halving them changes no integral here by
// more than kQuadratureTolerance / 10. Every stream is a Pcg32 with a fixed seed.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/scene/scene.h"
#include "tests/renderer/bsdf_test_support.h"
#include "renderer/bsdfs/beckmann.h"
#include "renderer/bsdfs/bsdf.h"
#include "renderer/bsdfs/microfacet.h"
#include "renderer/samplers/rng.h"

namespace rayfarm {
namespace {

using testing::AngleGrid;
using testing::chi_square_test;
using testing::ChiSquareResult;
using testing::for_each_node;
using testing::kTwoPi;
using testing::spherical;

constexpr double kPiD = 3.141592653589793;
constexpr double kDegree = kPiD / 180.0;
constexpr int kHypotheses = 200;
constexpr double kAlpha = 0.01;
const double kTestLevel = kAlpha / kHypotheses;
constexpr double kQuadratureTolerance = 1e-4;

struct Alphas {
  float u, v;
};
const Alphas kAlphas[] = {{0.02f, 0.02f}, {0.1f, 0.1f},  {0.5f, 0.5f},
                          {1.f, 1.f},     {0.05f, 0.4f}, {1.f, 0.1f}};

std::string name_of(const Alphas& a) { return std::to_string(a.u) + " x " + std::to_string(a.v); }

/// A grid over the micro-normals that carry all but exp(-36) of D: tan theta up to six times
/// the wider roughness.
AngleGrid normal_cap(const Alphas& a) {
  AngleGrid grid;
  grid.cos_lo = std::cos(std::atan(6.0 * std::max(a.u, a.v)));
  return grid;
}

double step_for(const Alphas& a) { return std::min(0.02, std::min(a.u, a.v) / 10.0); }

/// D in the angle form, in double: exp(-tan^2 (cos^2 phi / au^2 + sin^2 phi / av^2)) /
/// (pi au av cos^4).
double beckmann_d(double theta, double phi, double au, double av) {
  const double t = std::tan(theta), c = std::cos(theta);
  const double e = t * t * (std::pow(std::cos(phi) / au, 2.0) + std::pow(std::sin(phi) / av, 2.0));
  return std::exp(-e) / (kPiD * au * av * std::pow(c, 4.0));
}

// ----------------------------------------------------------------------------------------------
// The distribution

TEST(BeckmannTest, DMatchesTheAngleForm) {
  for (const Alphas& a : kAlphas) {
    const BeckmannDistribution beckmann(a.u, a.v);
    for (const double theta : {0.0, 0.01, 0.2, 0.7, 1.2, 1.5})
      for (const double phi : {0.0, 0.5, 1.9, 4.0}) {
        const double expected = beckmann_d(theta, phi, a.u, a.v);
        const double got = beckmann.d(spherical(theta, phi, 1));
        EXPECT_NEAR(got, expected, 1e-5 * expected + 1e-30)
            << name_of(a) << ", theta " << theta << ", phi " << phi;
      }
    EXPECT_EQ(beckmann.d({0.f, 0.6f, -0.8f}), 0.f);  // micro-normals face up
    EXPECT_EQ(beckmann.d({1.f, 0.f, 0.f}), 0.f);
  }
}

TEST(BeckmannTest, ProjectedNormalsAndVisibleNormalsIntegrateToOne) {
  // Integral of D(wm) wm.z over the hemisphere is 1; so is the visible normals' density for any w.
  for (const Alphas& a : kAlphas) {
    const BeckmannDistribution beckmann(a.u, a.v);
    const AngleGrid grid = normal_cap(a);
    double projected = 0.0;
    for_each_node(grid, step_for(a),
                  [&](int, const Vec3& wm, double w) { projected += w * beckmann.d(wm) * wm.z; });
    EXPECT_NEAR(projected, 1.0, kQuadratureTolerance) << name_of(a);
    for (const double theta : {0.0, 45.0, 85.0}) {
      const Vec3 wo = spherical(theta * kDegree, 0.7, 1);
      double visible = 0.0;
      for_each_node(grid, step_for(a), [&](int, const Vec3& wm, double w) {
        visible += w * beckmann.visible_pdf(wo, wm);
      });
      EXPECT_NEAR(visible, 1.0, kQuadratureTolerance) << name_of(a) << ", theta " << theta;
    }
  }
}

TEST(BeckmannTest, LambdaIsTheExactSmithForm) {
  // alpha 1 at 45 degrees: a = 1, Lambda = (erf(1) - 1) / 2 + exp(-1) / (2 sqrt(pi)).
  const BeckmannDistribution unit(1.f, 1.f);
  const float s = std::sqrt(0.5f);
  EXPECT_NEAR(unit.lambda({s, 0.f, s}),
              (std::erf(1.0) - 1.0) / 2.0 + std::exp(-1.0) / (2.0 * std::sqrt(kPiD)), 1e-6);
  EXPECT_EQ(unit.lambda({0.f, 0.f, 1.f}), 0.f);
  EXPECT_EQ(unit.g1({1.f, 0.f, 0.f}), 0.f);  // grazing: fully masked
  // Anisotropic: alpha(phi) = sqrt(cos^2 au^2 + sin^2 av^2); either side of the surface alike.
  const BeckmannDistribution aniso(0.2f, 0.6f);
  for (const double theta : {0.3, 1.0, 1.5})
    for (const double phi : {0.0, 0.8, 2.0}) {
      const Vec3 w = spherical(theta, phi, 1);
      const double alpha = std::hypot(0.2 * std::cos(phi), 0.6 * std::sin(phi));
      const double x = 1.0 / (alpha * std::tan(theta));
      const double expected =
          (std::erf(x) - 1.0) / 2.0 + std::exp(-x * x) / (2.0 * x * std::sqrt(kPiD));
      EXPECT_NEAR(aniso.lambda(w), expected, 1e-6 + 1e-5 * expected) << theta << " " << phi;
      EXPECT_EQ(aniso.lambda(w), aniso.lambda(spherical(theta, phi, -1)));
    }
}

TEST(BeckmannTest, G1IsTheMaskingIntegral) {
  // The projected area of the visible micro-surface equals the macro-surface's: G1(w) = w.z /
  // integral of max(0, w.wm) D(wm) over the micro-normals (the definition Smith's Lambda solves).
  for (const Alphas& a : kAlphas) {
    const BeckmannDistribution beckmann(a.u, a.v);
    for (const double theta : {20.0, 60.0, 80.0, 89.0})
      for (const double phi : {0.0, 0.7, 1.5708}) {
        const Vec3 w = spherical(theta * kDegree, phi, 1);
        double seen = 0.0;
        for_each_node(normal_cap(a), step_for(a), [&](int, const Vec3& wm, double weight) {
          seen += weight * std::max(0.0, double(dot(w, wm))) * beckmann.d(wm);
        });
        EXPECT_NEAR(beckmann.g1(w), w.z / seen, 2e-4 * beckmann.g1(w))
            << name_of(a) << ", theta " << theta << ", phi " << phi;
      }
  }
}

TEST(BeckmannTest, SmoothBelowTheThresholdOnBothAxesOnly) {
  EXPECT_TRUE(BeckmannDistribution(0.f, 0.f).is_smooth());
  EXPECT_TRUE(BeckmannDistribution(9e-5f, 0.f).is_smooth());
  EXPECT_FALSE(BeckmannDistribution(0.f, 0.2f).is_smooth());
  EXPECT_FALSE(BeckmannDistribution(kSmoothAlpha, kSmoothAlpha).is_smooth());
  const BeckmannDistribution one_axis(0.f, 0.2f);
  EXPECT_TRUE(std::isfinite(one_axis.d({0.f, 0.f, 1.f})));
  Pcg32 rng(11, 1);
  for (int k = 0; k < 1000; ++k) {
    const Vec3 wm = one_axis.sample_visible(normalize(Vec3{0.3f, 0.4f, 0.5f}), rng.next_float(),
                                            rng.next_float());
    ASSERT_TRUE(std::isfinite(wm.x) && std::isfinite(wm.y) && wm.z > 0.f);
    ASSERT_NEAR(length(wm), 1.f, 1e-5f);
  }
}

// ----------------------------------------------------------------------------------------------
// Sampling the visible normals

TEST(BeckmannSampleTest, SlopeInversionHitsItsDistributionFunction) {
  // K(x) / K(cot theta) = u, K the distribution function written independently with erf, in
  // long double; u = 0 and 1 stay finite (the ends of the bracket).
  Pcg32 rng(21, 1);
  for (const double theta : {0.0, 1e-4, 0.3, 1.0, 1.4, 1.5, 1.5707}) {
    const double c = std::cos(theta), s = std::sin(theta);
    const auto k = [&](long double x) {
      return c * (1.0L + std::erf(x)) / 2.0L + s * std::exp(-x * x) / (2.0L * std::sqrt(kPiD));
    };
    const long double top = s > 0.0 ? k(c / s) : 1.0L;
    for (int i = 0; i < 2000; ++i) {
      const double u = rng.next_float();
      const double x = beckmann_visible_slope(c, s, u);
      if (s > 0.0) {
        ASSERT_LE(x, c / s + 1e-12);
      }
      ASSERT_NEAR(double(k(x) / top), u, 1e-9) << "theta " << theta << ", u " << u;
    }
    for (const double u : {0.0, 1.0}) ASSERT_TRUE(std::isfinite(beckmann_visible_slope(c, s, u)));
  }
}

/// Chi-square of sample_visible(w) against visible_pdf(w, .) on the cap of micro-normals, with
/// one cell for the rest of the hemisphere.
void expect_visible_normals_follow_pdf(const Alphas& a, double theta_deg, uint64_t stream) {
  SCOPED_TRACE(name_of(a) + ", theta " + std::to_string(theta_deg));
  constexpr int kDraws = 100000;
  const BeckmannDistribution beckmann(a.u, a.v);
  const Vec3 w = spherical(theta_deg * kDegree, 0.9, 1);
  const AngleGrid grid = normal_cap(a);
  const int n = grid.bins();
  std::vector<double> expected(n + 1, 0.0), observed(n + 1, 0.0);
  for_each_node(grid, step_for(a), [&](int b, const Vec3& wm, double weight) {
    expected[b] += weight * beckmann.visible_pdf(w, wm);
  });
  double total = 0.0;
  for (int b = 0; b < n; ++b) total += expected[b];
  EXPECT_NEAR(total, 1.0, kQuadratureTolerance);
  expected[n] = std::max(0.0, 1.0 - total);
  for (double& e : expected) e *= kDraws;
  Pcg32 rng(31, stream);
  for (int k = 0; k < kDraws; ++k) {
    const Vec3 wm = beckmann.sample_visible(w, rng.next_float(), rng.next_float());
    ASSERT_NEAR(length(wm), 1.f, 1e-5f);
    ASSERT_GT(dot(w, wm), -1e-6f) << "a back-facing micro-normal";
    const int b = grid.bin_of(wm);
    observed[b >= 0 ? b : n] += 1.0;
  }
  const ChiSquareResult r = chi_square_test(observed, expected);
  EXPECT_GE(r.p_value, kTestLevel) << "chi2 " << r.statistic << ", dof " << r.dof << " " << r.note;
}

TEST(BeckmannSampleTest, VisibleNormalsFollowTheirDensity) {
  uint64_t stream = 0;
  for (const Alphas& a : kAlphas)
    for (const double theta : {0.0, 40.0, 75.0, 89.0})
      expect_visible_normals_follow_pdf(a, theta, ++stream);
}

// ----------------------------------------------------------------------------------------------
// The three rough BSDFs at alpha 0.02: chi-square in caps around the lobes

/// A cap of directions around `centre`, of half-angle `half_angle`: a grid in the frame whose z
/// axis is `centre`.
struct Cap {
  Vec3 centre, t, b;
  AngleGrid grid;

  Cap(const Vec3& c, double half_angle) : centre(normalize(c)) {
    const Vec3 helper = std::fabs(centre.z) < 0.9f ? Vec3{0.f, 0.f, 1.f} : Vec3{1.f, 0.f, 0.f};
    t = normalize(cross(helper, centre));
    b = cross(centre, t);
    grid.cos_lo = std::cos(half_angle);
  }
  Vec3 to_world(const Vec3& w) const { return t * w.x + b * w.y + centre * w.z; }
  /// The cell of wi, or -1 outside the cap. The cosine is clamped to 1: rounding puts the
  /// directions nearest the centre just above it.
  int bin_of(const Vec3& wi) const {
    return grid.bin_of({dot(wi, t), dot(wi, b), std::min(1.f, dot(wi, centre))});
  }
};

/// Snell's direction of wo through the macro-surface (z the normal; ior inside, below z = 0); false
/// under total internal reflection.
bool refract_macro(const Vec3& wo, float ior, Vec3& wt) {
  const float eta = wo.z > 0.f ? 1.f / ior : ior;  // n_o / n_t
  const float sin2 = eta * eta * (1.f - wo.z * wo.z);
  if (sin2 >= 1.f) return false;
  const float cos_t = std::sqrt(1.f - sin2);
  wt = normalize(Vec3{-eta * wo.x, -eta * wo.y, wo.z > 0.f ? -cos_t : cos_t});
  return true;
}

/// Chi-square of sample() against pdf() in caps around the mirror direction and (for glass) the
/// refracted one, each of half-angle 10 alpha_max (the micro-normals beyond 5 alpha carry
/// exp(-25) of D, and reflection turns wi by at most twice the micro-normal's tilt), and one cell
/// for every other direction, rejected samples and Dirac ones. Quadrature cells of alpha_min / 10.
void expect_narrow_lobe_follows_pdf(const std::string& name, const MaterialKind& kind,
                                    const Alphas& a, float ior, double theta_deg, uint64_t stream) {
  SCOPED_TRACE(name + ", wo theta " + std::to_string(theta_deg));
  constexpr int kDraws = 200000;
  Material m;
  m.kind = kind;
  const Bsdf bsdf(m);
  const Vec3 wo = spherical(theta_deg * kDegree, 0.3, 1);
  const double half_angle = 10.0 * std::max(a.u, a.v), step = std::min(a.u, a.v) / 10.0;
  std::vector<Cap> caps{Cap(reflect_z(wo), half_angle)};
  Vec3 wt;
  if (ior != 1.f && refract_macro(wo, ior, wt)) {
    ASSERT_LT(dot(wt, caps[0].centre), std::cos(2.0 * half_angle)) << "caps overlap";
    caps.emplace_back(wt, half_angle);
  }
  const int n = caps[0].grid.bins();
  const int rest = n * int(caps.size());
  std::vector<double> expected(rest + 1, 0.0), observed(rest + 1, 0.0);
  for (size_t c = 0; c < caps.size(); ++c)
    for_each_node(caps[c].grid, step, [&](int b, const Vec3& w, double weight) {
      expected[c * n + b] += weight * bsdf.pdf(wo, caps[c].to_world(w));
    });
  double total = 0.0;
  for (int b = 0; b < rest; ++b) total += expected[b];
  EXPECT_LE(total, 1.0 + kQuadratureTolerance);
  expected[rest] = std::max(0.0, 1.0 - total);
  for (double& e : expected) e *= kDraws;
  Pcg32 rng(41, stream);
  for (int k = 0; k < kDraws; ++k) {
    BsdfSample out;
    const float u_lobe = rng.next_float(), u1 = rng.next_float(), u2 = rng.next_float();
    int cell = rest;
    if (bsdf.sample(wo, u_lobe, u1, u2, out) && !out.specular) {
      for (size_t c = 0; c < caps.size() && cell == rest; ++c) {
        const int b = caps[c].bin_of(out.wi);
        if (b >= 0) cell = int(c) * n + b;
      }
    }
    observed[cell] += 1.0;
  }
  const ChiSquareResult r = chi_square_test(observed, expected);
  EXPECT_GE(r.p_value, kTestLevel) << "chi2 " << r.statistic << ", dof " << r.dof << " " << r.note;
}

TEST(BeckmannBsdfTest, NarrowLobesFollowPdf) {
  uint64_t stream = 0;
  for (const Alphas& a : {Alphas{0.02f, 0.02f}, Alphas{0.02f, 0.04f}}) {
    RoughConductorMaterial gold;
    gold.alpha_u = a.u;
    gold.alpha_v = a.v;
    gold.distribution = MicrofacetType::kBeckmann;
    RoughDielectricMaterial glass;
    glass.ior = 1.5f;
    glass.alpha_u = a.u;
    glass.alpha_v = a.v;
    glass.distribution = MicrofacetType::kBeckmann;
    for (const double theta : {0.0, 50.0, 80.0, 130.0}) {
      expect_narrow_lobe_follows_pdf("gold " + name_of(a), gold, a, 1.f, theta, ++stream);
      expect_narrow_lobe_follows_pdf("glass " + name_of(a), glass, a, 1.5f, theta, ++stream);
    }
    // The plastic's coating is isotropic.
    PlasticMaterial plastic;
    plastic.diffuse_reflectance = Vec3(0.5f);
    plastic.alpha = a.u;
    plastic.distribution = MicrofacetType::kBeckmann;
    if (a.u == a.v)
      for (const double theta : {0.0, 50.0, 80.0, 130.0})
        expect_narrow_lobe_follows_pdf("plastic " + name_of(a), plastic, a, 1.f, theta, ++stream);
  }
}

}  // namespace
}  // namespace rayfarm
