// The BSDFs (renderer/bsdfs/bsdf.h) against their own definitions: sample() agrees with pdf() and
// eval(), the pdf integrates to one, eval() is reciprocal and conserves energy, the sampled
// directions follow pdf() (chi-square), and the specular lobes follow the law of reflection,
// Snell's law and the Fresnel equations.
//
// Statistics. Every Monte Carlo assertion is one hypothesis test; the family of all of them in this
// file is held at significance kAlpha = 0.01 by a Bonferroni correction: each runs at
// kAlpha / kHypotheses. A proportion or a mean is compared with a two-sided z test whose threshold
// solves P(|Z| > z) = kAlpha / kHypotheses (z = 4.2 here); a histogram is compared with a
// chi-square test whose p-value must exceed kAlpha / kHypotheses. Integrals over the sphere are
// deterministic quadratures (2 x 2 Gauss-Legendre nodes per cell of at most a quarter of the
// lobe's angular width), accurate to better than kQuadratureTolerance. Every stream is a Pcg32
// with a fixed seed, so each run draws the same numbers.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <map>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include <gtest/gtest.h>

#include "common/math/vec3.h"
#include "common/scene/scene.h"
#include "tests/support/normal_quantile.h"
#include "tests/renderer/bsdf_test_support.h"
#include "renderer/bsdfs/bsdf.h"
#include "renderer/samplers/rng.h"

namespace rayfarm {
namespace {

constexpr double kDegree = 3.141592653589793 / 180.0;

using testing::AngleGrid;
using testing::chi_square_survival;
using testing::chi_square_test;
using testing::ChiSquareResult;
using testing::for_each_node;
using testing::kTwoPi;
using testing::spherical;
using testing::two_sided_z;
using testing::uniform_sphere;

/// Largest quadrature cell for a material: a quarter of the Phong lobe's angular width 1/sqrt(n).
double quadrature_step(const Material& m) {
  const auto* phong = std::get_if<PhongMaterial>(&m.kind);
  if (phong == nullptr) return 0.02;
  return std::min(0.02, 1.0 / (4.0 * std::sqrt(double(phong->exponent))));
}

struct HemisphereIntegrals {
  double pdf = 0.0;       // integral of pdf(wo, wi) over wo's hemisphere
  double albedo[3] = {};  // integral of eval(wo, wi) over it, per channel
};

HemisphereIntegrals integrate_hemisphere(const Bsdf& bsdf, const Material& m, const Vec3& wo) {
  AngleGrid grid;
  grid.side = wo.z > 0.f ? 1 : -1;
  HemisphereIntegrals r;
  for_each_node(grid, quadrature_step(m), [&](int, const Vec3& wi, double weight) {
    r.pdf += weight * bsdf.pdf(wo, wi);
    const Vec3 f = bsdf.eval(wo, wi);
    for (int c = 0; c < 3; ++c) r.albedo[c] += weight * f[c];
  });
  return r;
}

// ----------------------------------------------------------------------------------------------
// Materials and cases

Material diffuse(float albedo) {
  Material m;
  m.name = "diffuse";
  m.kind = DiffuseMaterial{Vec3(albedo)};
  return m;
}

Material phong(const Vec3& kd, const Vec3& ks, float exponent) {
  Material m;
  m.name = "phong n=" + std::to_string(int(exponent)) + " kd.g=" + std::to_string(kd.y) +
           " ks.g=" + std::to_string(ks.y);
  m.kind = PhongMaterial{kd, ks, exponent};
  return m;
}

Material dielectric(float ior, const Vec3& tint = Vec3(1.f)) {
  Material m;
  m.name = "dielectric ior=" + std::to_string(ior);
  m.kind = DielectricMaterial{ior, tint};
  return m;
}

const float kExponents[] = {1.f, 10.f, 100.f, 1000.f};
struct PhongWeights {
  Vec3 kd, ks;
};
// kd + ks <= 1 per channel: a mixed lobe, a pure specular lobe, and coloured weights whose
// luminance ratio (the lobe selection probability) differs from any channel's ratio.
const PhongWeights kPhongWeights[] = {
    {Vec3(0.5f), Vec3(0.4f)},
    {Vec3(0.f), Vec3(0.9f)},
    {Vec3(0.6f, 0.2f, 0.1f), Vec3(0.1f, 0.3f, 0.2f)},
};

/// Diffuse (albedo 0.7) and every Phong weight with every exponent.
std::vector<Material> non_specular_materials() {
  std::vector<Material> ms = {diffuse(0.7f)};
  for (const PhongWeights& w : kPhongWeights)
    for (float n : kExponents) ms.push_back(phong(w.kd, w.ks, n));
  return ms;
}

/// Outgoing directions, in the plane phi = 0: normal, oblique, grazing, and one below the surface.
const double kWoThetaDeg[] = {0.0, 30.0, 60.0, 80.0, 89.0, 120.0};
Vec3 wo_at(double theta_deg) { return spherical(theta_deg * kDegree, 0.0, 1); }

/// non_specular_materials(), built once.
const std::vector<Material>& materials() {
  static const std::vector<Material> ms = non_specular_materials();
  return ms;
}

/// Integrals over wo's hemisphere for materials()[index] and wo_at(theta_deg), computed once.
const HemisphereIntegrals& hemisphere_integrals(size_t index, double theta_deg) {
  static std::map<std::pair<size_t, double>, HemisphereIntegrals> cache;
  const auto key = std::make_pair(index, theta_deg);
  auto it = cache.find(key);
  if (it == cache.end()) {
    const Material& m = materials()[index];
    it = cache.emplace(key, integrate_hemisphere(Bsdf(m), m, wo_at(theta_deg))).first;
  }
  return it->second;
}

constexpr int kMaterialCount = 1 + int(std::size(kPhongWeights) * std::size(kExponents));
constexpr int kWoCount = int(std::size(kWoThetaDeg));

// Chi-square cases: (material index into non_specular_materials(), wo theta in degrees).
struct ChiSquareCase {
  int material;
  double theta_deg;
};
const ChiSquareCase kChiSquareCases[] = {
    // diffuse
    {0, 0.0},
    {0, 60.0},
    {0, 120.0},
    // kd 0.5, ks 0.4: n = 1, 10, 100, 1000
    {1, 0.0},
    {1, 45.0},
    {1, 80.0},
    {2, 0.0},
    {2, 45.0},
    {2, 80.0},
    {3, 0.0},
    {3, 45.0},
    {3, 80.0},
    {4, 0.0},
    {4, 45.0},
    {4, 80.0},
    {4, 130.0},
    // pure specular: n = 10, 100, 1000
    {6, 30.0},
    {7, 30.0},
    {8, 30.0},
    {8, 75.0},
    // coloured: n = 10, 100, 1000
    {10, 20.0},
    {11, 60.0},
    {12, 70.0},
};
constexpr int kChiSquareCount = int(std::size(kChiSquareCases));

// Dielectric cases: an interface seen from outside (side +1) or inside (side -1).
struct DielectricCase {
  float ior;
  int side;
};
// Glass and diamond from both sides, water seen from inside, an air bubble in water (ior 1/1.33)
// from both sides, and an index-matched interface.
const DielectricCase kDielectricCases[] = {
    {1.5f, 1},        {1.5f, -1},        {2.4f, 1}, {2.4f, -1}, {1.33f, -1},
    {1.f / 1.33f, 1}, {1.f / 1.33f, -1}, {1.f, 1},  {1.f, -1},
};
const double kFresnelThetaDeg[] = {0.0, 20.0, 40.0, 45.0, 60.0, 85.0};
constexpr int kDielectricCount = int(std::size(kDielectricCases));
constexpr int kFresnelThetaCount = int(std::size(kFresnelThetaDeg));

// The family of hypothesis tests of this file (for the Bonferroni correction).
constexpr int kHypotheses = kMaterialCount * kWoCount        // rejected fraction
                            + kMaterialCount * kWoCount * 3  // albedo by sampling, per channel
                            + kChiSquareCount                // chi-square
                            + kDielectricCount * kFresnelThetaCount;  // reflected fraction
constexpr double kAlpha = 0.01;
const double kTestLevel = kAlpha / kHypotheses;
const double kZ = two_sided_z(kTestLevel);

/// Bound on the error of the hemisphere integrals (of pdf and of eval). The quadrature changes by
/// less than 4e-6 when its cells are halved, for every material and wo here; the rest is float
/// rounding of the directions themselves: a float wo of length 1 +- 2^-24 scales cos^n by up to
/// n 2^-24 = 6e-5 for n = 1000 (the integral of the double-precision lobe is 1 within 1e-6).
constexpr double kQuadratureTolerance = 1e-4;

/// Draws one sample with three numbers from rng, in a fixed order.
bool draw(const Bsdf& bsdf, const Vec3& wo, Pcg32& rng, BsdfSample& out) {
  const float u_lobe = rng.next_float();
  const float u1 = rng.next_float();
  const float u2 = rng.next_float();
  return bsdf.sample(wo, u_lobe, u1, u2, out);
}

bool near_relative(double a, double b, double rel) {
  return std::fabs(a - b) <= rel * std::max(std::fabs(a), std::fabs(b)) + 1e-30;
}

// ----------------------------------------------------------------------------------------------
// The statistics helpers themselves, against tabulated values.

TEST(StatisticsTest, QuantilesMatchTables) {
  EXPECT_NEAR(two_sided_z(0.05), 1.959964, 1e-6);
  EXPECT_NEAR(two_sided_z(0.01), 2.575829, 1e-6);
  EXPECT_NEAR(chi_square_survival(3.841459, 1), 0.05, 1e-6);
  EXPECT_NEAR(chi_square_survival(23.209251, 10), 0.01, 1e-6);
  EXPECT_NEAR(chi_square_survival(135.806723, 100), 0.01, 1e-6);
  EXPECT_NEAR(chi_square_survival(2.0, 2), std::exp(-1.0), 1e-12);  // Q(1, x) = exp(-x)
  EXPECT_GT(kZ, 3.5);
  EXPECT_LT(kZ, 5.0);
}

TEST(StatisticsTest, ChiSquareTestPoolsSmallCellsAndRejectsImpossibleEvents) {
  const ChiSquareResult fit = chi_square_test({10, 10, 1, 2, 0}, {10, 10, 1, 2, 0});
  EXPECT_EQ(fit.statistic, 0.0);
  EXPECT_EQ(fit.dof, 1);  // {0, 1, 2} pooled with one of the 10s
  EXPECT_EQ(chi_square_test({10, 10, 1}, {10, 10.5, 0.5}).dof, 1);
  EXPECT_EQ(chi_square_test({10, 9, 1}, {10, 10, 0}).p_value, 0.0);
}

// ----------------------------------------------------------------------------------------------
// sample() against pdf() and eval()

TEST(BsdfSampleTest, PdfAndWeightAgreeWithPdfAndEval) {
  Pcg32 rng(11, 1);
  for (const Material& m : materials()) {
    SCOPED_TRACE(m.name);
    const Bsdf bsdf(m);
    EXPECT_FALSE(bsdf.is_specular());
    int accepted = 0;
    for (int k = 0; k < 400; ++k) {
      const Vec3 wo = uniform_sphere(rng);
      for (int s = 0; s < 40; ++s) {
        BsdfSample out;
        if (!draw(bsdf, wo, rng, out)) continue;
        ++accepted;
        ASSERT_FALSE(out.specular);
        ASSERT_NEAR(length(out.wi), 1.f, 1e-5f);
        ASSERT_GT(out.wi.z * wo.z, 0.f) << "wi on the other side of the surface";
        const float pdf = bsdf.pdf(wo, out.wi);
        ASSERT_GT(pdf, 0.f);
        ASSERT_TRUE(near_relative(out.pdf, pdf, 1e-4)) << out.pdf << " vs " << pdf;
        const Vec3 f = bsdf.eval(wo, out.wi);
        for (int c = 0; c < 3; ++c)
          ASSERT_TRUE(near_relative(out.weight[c], f[c] / pdf, 1e-4))
              << "channel " << c << ": " << out.weight[c] << " vs " << f[c] / pdf;
      }
    }
    EXPECT_GT(accepted, 400 * 40 / 2);
  }
}

TEST(BsdfSampleTest, NothingOnTheOtherSide) {
  Pcg32 rng(12, 1);
  for (const Material& m : materials()) {
    SCOPED_TRACE(m.name);
    const Bsdf bsdf(m);
    for (int k = 0; k < 2000; ++k) {
      const Vec3 wo = uniform_sphere(rng);
      Vec3 wi = uniform_sphere(rng);
      if (wi.z * wo.z > 0.f) wi.z = -wi.z;
      ASSERT_EQ(bsdf.pdf(wo, wi), 0.f);
      ASSERT_TRUE(is_black(bsdf.eval(wo, wi)));
    }
  }
}

// ----------------------------------------------------------------------------------------------
// Normalisation, reciprocity, energy

TEST(BsdfIntegralTest, PdfIntegratesToOneAndSampleRejectsTheRest) {
  // pdf() integrates to 1 over wo's hemisphere, except for the part of a Phong lobe that falls
  // below the horizon: sample() draws that part and rejects it, so its rejected fraction must be
  // 1 - integral (binomial z test, N draws; the standard error uses at least one count's worth of
  // probability so that an expected fraction of 0 still admits float rounding at the horizon).
  constexpr int kDraws = 100000;
  Pcg32 rng(21, 1);
  for (size_t index = 0; index < materials().size(); ++index) {
    const Material& m = materials()[index];
    const Bsdf bsdf(m);
    for (double theta : kWoThetaDeg) {
      SCOPED_TRACE(m.name + ", wo theta " + std::to_string(theta));
      const Vec3 wo = wo_at(theta);
      const double integral = hemisphere_integrals(index, theta).pdf;
      if (std::holds_alternative<DiffuseMaterial>(m.kind) || theta == 0.0) {
        EXPECT_NEAR(integral, 1.0, kQuadratureTolerance);  // the whole lobe is above the horizon
      } else {
        EXPECT_LE(integral, 1.0 + kQuadratureTolerance);
        EXPECT_GT(integral, 0.4);
      }
      int rejected = 0;
      for (int k = 0; k < kDraws; ++k) {
        BsdfSample out;
        if (!draw(bsdf, wo, rng, out)) ++rejected;
      }
      const double expected = std::max(0.0, 1.0 - integral);
      const double q = std::max(expected, 1.0 / kDraws);
      const double tolerance = kZ * std::sqrt(q * (1.0 - q) / kDraws) + kQuadratureTolerance;
      EXPECT_NEAR(double(rejected) / kDraws, expected, tolerance) << "integral " << integral;
    }
  }
}

TEST(BsdfIntegralTest, Reciprocity) {
  // f(wo, wi) = eval(wo, wi) / |cos wi| is symmetric. Half of the pairs are uniform on the sphere,
  // half are drawn by sample() so that narrow lobes are visited too.
  Pcg32 rng(31, 1);
  for (const Material& m : materials()) {
    SCOPED_TRACE(m.name);
    const Bsdf bsdf(m);
    int nonzero = 0;
    for (int k = 0; k < 20000; ++k) {
      const Vec3 wo = uniform_sphere(rng);
      Vec3 wi = uniform_sphere(rng);
      BsdfSample out;
      if (k % 2 == 1 && draw(bsdf, wo, rng, out)) wi = out.wi;
      if (wo.z == 0.f || wi.z == 0.f) continue;
      const Vec3 f_oi = bsdf.eval(wo, wi) / std::fabs(wi.z);
      const Vec3 f_io = bsdf.eval(wi, wo) / std::fabs(wo.z);
      nonzero += !is_black(f_oi);
      for (int c = 0; c < 3; ++c)
        ASSERT_TRUE(near_relative(f_oi[c], f_io[c], 1e-4))
            << "channel " << c << ": " << f_oi[c] << " vs " << f_io[c];
    }
    EXPECT_GT(nonzero, 20000 / 4);
  }
}

TEST(BsdfIntegralTest, EnergyIsConserved) {
  // The directional albedo, the integral of eval(wo, .) over the sphere, is at most kd + ks
  // (<= 1) for every wo, equal to it at normal incidence (the normalised Phong lobe), and equal
  // to the albedo for the diffuse surface. The mean sample weight (0 for a rejected sample) is an
  // unbiased estimate of the same integral: z test with the standard error of the N weights.
  constexpr int kDraws = 100000;
  Pcg32 rng(41, 1);
  for (size_t index = 0; index < materials().size(); ++index) {
    const Material& m = materials()[index];
    const Bsdf bsdf(m);
    const auto* diffuse = std::get_if<DiffuseMaterial>(&m.kind);
    const auto* phong = std::get_if<PhongMaterial>(&m.kind);
    const Vec3 bound = diffuse != nullptr ? diffuse->albedo.value : phong->kd + phong->ks;
    for (double theta : kWoThetaDeg) {
      SCOPED_TRACE(m.name + ", wo theta " + std::to_string(theta));
      const Vec3 wo = wo_at(theta);
      const HemisphereIntegrals& in = hemisphere_integrals(index, theta);
      double sum[3] = {}, sum2[3] = {};
      for (int k = 0; k < kDraws; ++k) {
        BsdfSample out;
        if (!draw(bsdf, wo, rng, out)) continue;
        for (int c = 0; c < 3; ++c) {
          sum[c] += out.weight[c];
          sum2[c] += double(out.weight[c]) * out.weight[c];
        }
      }
      for (int c = 0; c < 3; ++c) {
        SCOPED_TRACE("channel " + std::to_string(c));
        EXPECT_LE(in.albedo[c], 1.0 + kQuadratureTolerance);
        EXPECT_LE(in.albedo[c], bound[c] + kQuadratureTolerance);
        if (std::holds_alternative<DiffuseMaterial>(m.kind) || theta == 0.0) {
          EXPECT_NEAR(in.albedo[c], bound[c], kQuadratureTolerance);
        }
        const double mean = sum[c] / kDraws;
        const double variance = std::max(0.0, sum2[c] / kDraws - mean * mean);
        const double se = std::sqrt(variance / (kDraws - 1));
        EXPECT_NEAR(mean, in.albedo[c], kZ * se + kQuadratureTolerance);
      }
    }
  }
}

// ----------------------------------------------------------------------------------------------
// Chi-square test of sample() against pdf()

/// The grid of a chi-square case: 10 x 20 bins in (cos theta, phi) over wo's hemisphere for wide
/// lobes; for narrow Phong lobes (n >= 100) the same 10 x 20 bins over a window of half-width
/// 4 / sqrt(n) radians around the mirror direction, the rest of the hemisphere being one cell.
AngleGrid chi_square_grid(const Material& m, const Vec3& wo) {
  AngleGrid grid;
  grid.side = wo.z > 0.f ? 1 : -1;
  const auto* phong = std::get_if<PhongMaterial>(&m.kind);
  if (phong == nullptr || phong->exponent < 100.f) return grid;
  const double half_width = 4.0 / std::sqrt(double(phong->exponent));
  const double theta_r = std::acos(std::fabs(double(wo.z)));  // mirror direction, at phi = pi
  const double theta_lo = std::max(0.0, theta_r - half_width);
  const double theta_hi = std::min(0.5 * 3.141592653589793, theta_r + half_width);
  grid.cos_lo = std::cos(theta_hi);
  grid.cos_hi = std::cos(theta_lo);
  if (theta_lo > 0.0 && std::sin(half_width) < std::sin(theta_lo)) {
    const double dphi = std::asin(std::sin(half_width) / std::sin(theta_lo));
    grid.phi_lo = 3.141592653589793 - dphi;
    grid.phi_hi = 3.141592653589793 + dphi;
  }
  return grid;
}

TEST(BsdfChiSquareTest, SampledDirectionsFollowPdf) {
  // Cells: the grid's bins, the rest of wo's hemisphere, and the rejected samples. Expected
  // counts: N times the quadrature of pdf() over each bin; the rest is integral - sum of bins;
  // rejected is 1 - integral.
  constexpr int kDraws = 1000000;
  for (const ChiSquareCase& cs : kChiSquareCases) {
    const Material& m = materials()[cs.material];
    SCOPED_TRACE(m.name + ", wo theta " + std::to_string(cs.theta_deg));
    const Bsdf bsdf(m);
    const Vec3 wo = wo_at(cs.theta_deg);
    const AngleGrid grid = chi_square_grid(m, wo);
    const int rest = grid.bins(), rejected = grid.bins() + 1;

    std::vector<double> expected(grid.bins() + 2, 0.0);
    for_each_node(grid, quadrature_step(m), [&](int bin, const Vec3& wi, double weight) {
      expected[bin] += weight * bsdf.pdf(wo, wi);
    });
    const double integral = hemisphere_integrals(cs.material, cs.theta_deg).pdf;
    double on_grid = 0.0;
    for (int b = 0; b < grid.bins(); ++b) on_grid += expected[b];
    expected[rest] = std::max(0.0, integral - on_grid);
    expected[rejected] = std::max(0.0, 1.0 - integral);
    for (double& e : expected) e *= kDraws;

    std::vector<double> observed(expected.size(), 0.0);
    Pcg32 rng(51, uint64_t(cs.material * 1000 + cs.theta_deg));
    for (int k = 0; k < kDraws; ++k) {
      BsdfSample out;
      if (!draw(bsdf, wo, rng, out)) {
        observed[rejected] += 1.0;
        continue;
      }
      const int bin = grid.bin_of(out.wi);
      observed[bin < 0 ? rest : bin] += 1.0;
    }
    const ChiSquareResult r = chi_square_test(observed, expected);
    EXPECT_GE(r.p_value, kTestLevel)
        << "chi2 " << r.statistic << ", dof " << r.dof << " " << r.note;
  }
}

// ----------------------------------------------------------------------------------------------
// Mirror

TEST(MirrorTest, ReflectsAboutTheNormalWithItsReflectance) {
  Material m;
  const Vec3 reflectance(0.9f, 0.5f, 0.25f);
  m.kind = MirrorMaterial{reflectance};
  const Bsdf bsdf(m);
  EXPECT_TRUE(bsdf.is_specular());
  Pcg32 rng(61, 1);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 wo = uniform_sphere(rng);
    if (wo.z == 0.f) continue;
    BsdfSample out;
    ASSERT_TRUE(draw(bsdf, wo, rng, out));
    EXPECT_TRUE(out.specular);
    EXPECT_EQ(out.wi, Vec3(-wo.x, -wo.y, wo.z));
    EXPECT_EQ(out.weight, reflectance);
    EXPECT_EQ(out.pdf, 0.f);
    EXPECT_TRUE(is_black(bsdf.eval(wo, out.wi)));
    EXPECT_EQ(bsdf.pdf(wo, out.wi), 0.f);
  }
}

// ----------------------------------------------------------------------------------------------
// Dielectric

/// Fresnel reflectance from the angle forms of the Fresnel equations (independent of the
/// renderer's cosine forms): r_s = -sin(ti - tt) / sin(ti + tt), r_p = tan(ti - tt) / tan(ti + tt).
double fresnel_reference(double cos_i, double eta) {
  const double ti = std::acos(cos_i);
  const double sin_t = std::sin(ti) / eta;
  if (sin_t >= 1.0) return 1.0;
  const double tt = std::asin(sin_t);
  if (ti < 1e-7) return ((eta - 1.0) / (eta + 1.0)) * ((eta - 1.0) / (eta + 1.0));
  const double rs = std::sin(ti - tt) / std::sin(ti + tt);
  const double rp = std::tan(ti - tt) / std::tan(ti + tt);
  return 0.5 * (rs * rs + rp * rp);
}

TEST(FresnelTest, FourPercentAtNormalIncidenceOnGlass) {
  float cos_t = 0.f;
  EXPECT_NEAR(fresnel_dielectric(1.f, 1.5f, cos_t), 0.04f, 1e-6f);
  EXPECT_NEAR(cos_t, 1.f, 1e-6f);
  EXPECT_NEAR(fresnel_dielectric(1.f, 1.f / 1.5f, cos_t), 0.04f, 1e-6f);
  EXPECT_NEAR(cos_t, 1.f, 1e-6f);
}

TEST(FresnelTest, MatchesTheFresnelEquationsAndStaysInUnitInterval) {
  for (const float eta : {1.5f, 1.f / 1.5f, 2.4f, 1.f / 2.4f, 1.33f, 1.f / 1.33f, 1.1f}) {
    for (int k = 1; k <= 1000; ++k) {
      const float cos_i = k / 1000.f;
      float cos_t = -1.f;
      const float f = fresnel_dielectric(cos_i, eta, cos_t);
      SCOPED_TRACE("eta " + std::to_string(eta) + ", cos_i " + std::to_string(cos_i));
      ASSERT_GE(f, 0.f);
      ASSERT_LE(f, 1.f);
      ASSERT_NEAR(f, fresnel_reference(cos_i, eta), 2e-5);
      const double sin2_t = (1.0 - double(cos_i) * cos_i) / (double(eta) * eta);
      if (sin2_t < 1.0) {
        ASSERT_NEAR(cos_t, std::sqrt(1.0 - sin2_t), 1e-5);
      }
    }
  }
}

TEST(FresnelTest, TotalInternalReflectionBeyondTheCriticalAngle) {
  for (const float ior : {1.5f, 2.4f, 1.33f}) {
    const double cos_critical = std::sqrt(1.0 - 1.0 / (double(ior) * ior));
    SCOPED_TRACE("ior " + std::to_string(ior));
    for (int k = 1; k <= 100; ++k) {
      const double cos_i = cos_critical * k / 100.0 * 0.999;
      float cos_t = -1.f;
      EXPECT_EQ(fresnel_dielectric(float(cos_i), 1.f / ior, cos_t), 1.f) << cos_i;
    }
    float cos_t = -1.f;
    EXPECT_LT(fresnel_dielectric(float(cos_critical) * 1.01f, 1.f / ior, cos_t), 1.f);
    // From inside, beyond the critical angle, sample() reflects whatever u_lobe is.
    const Material glass = dielectric(ior);
    const Bsdf bsdf(glass);
    const double theta = std::acos(cos_critical * 0.9);
    const Vec3 wo = spherical(theta, 0.7, -1);
    for (const float u : {0.f, 0.5f, 0.999999f}) {
      BsdfSample out;
      ASSERT_TRUE(bsdf.sample(wo, u, 0.5f, 0.5f, out));
      EXPECT_EQ(out.wi, Vec3(-wo.x, -wo.y, wo.z));
      EXPECT_EQ(out.weight, Vec3(1.f));
    }
  }
}

TEST(DielectricTest, IndexOneIsInvisible) {
  const Material air = dielectric(1.f, Vec3(0.9f, 0.8f, 0.7f));
  const Bsdf bsdf(air);
  for (int k = 1; k <= 100; ++k) {
    float cos_t = -1.f;
    EXPECT_NEAR(fresnel_dielectric(k / 100.f, 1.f, cos_t), 0.f, 1e-7f);  // rounding of cos_t only
  }
  Pcg32 rng(71, 1);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 wo = uniform_sphere(rng);
    if (std::fabs(wo.z) < 1e-3f) continue;  // see IndexOneAtGrazingIncidence
    BsdfSample out;
    ASSERT_TRUE(draw(bsdf, wo, rng, out));
    ASSERT_TRUE(out.specular);
    ASSERT_NEAR(out.wi.x, -wo.x, 1e-6f);
    ASSERT_NEAR(out.wi.y, -wo.y, 1e-6f);
    // cos_t = sqrt(1 - sin_t^2) with sin_t^2 rounded by up to 2^-24: cos_t moves by up to
    // 2^-24 / (2 cos_t), which grows at grazing incidence.
    ASSERT_NEAR(out.wi.z, -wo.z, 1e-6f + 3e-8f / std::fabs(wo.z));
    ASSERT_EQ(out.weight, std::get<DielectricMaterial>(air.kind).tint);
  }
}

// An index-matched interface lets grazing rays through: computing sin_t^2 = (1 - cos_i^2) / eta^2
// rounds to exactly 1 for eta = 1 and cos_i below about 1.7e-4 and would report total internal
// reflection; cos_t^2 is computed as (eta^2 - 1 + cos_i^2) / eta^2 instead.
TEST(DielectricTest, IndexOneAtGrazingIncidence) {
  for (const float cos_i : {1e-4f, 1.5e-4f, 1e-5f}) {
    float cos_t = -1.f;
    EXPECT_NEAR(fresnel_dielectric(cos_i, 1.f, cos_t), 0.f, 1e-6f) << cos_i;
    EXPECT_NEAR(cos_t, cos_i, 1e-6f) << cos_i;
  }
  const Material air = dielectric(1.f);
  const Bsdf bsdf(air);
  const Vec3 wo{std::sqrt(1.f - 1e-8f), 0.f, 1e-4f};
  BsdfSample out;
  ASSERT_TRUE(bsdf.sample(wo, 0.5f, 0.5f, 0.5f, out));
  EXPECT_LT(out.wi.z, 0.f) << "reflected instead of passing through";
}

TEST(DielectricTest, RefractionObeysSnellAndCarriesTintOverEtaSquared) {
  const Vec3 tint(0.9f, 0.7f, 0.5f);
  Pcg32 rng(81, 1);
  for (const DielectricCase& dc : kDielectricCases) {
    const Material glass = dielectric(dc.ior, tint);
    const Bsdf bsdf(glass);
    const double eta = dc.side > 0 ? dc.ior : 1.0 / dc.ior;  // eta_t / eta_i
    SCOPED_TRACE(glass.name + (dc.side > 0 ? " from outside" : " from inside"));
    int refracted = 0;
    for (int k = 0; k < 5000; ++k) {
      Vec3 wo = uniform_sphere(rng);
      if (wo.z * dc.side < 0.f) wo.z = -wo.z;
      if (std::fabs(wo.z) < 1e-3f) continue;  // F -> 1 at grazing incidence
      const double sin_i = std::sqrt(double(wo.x) * wo.x + double(wo.y) * wo.y);
      if (sin_i / eta >= 0.999) continue;  // total internal reflection
      BsdfSample out;
      ASSERT_TRUE(bsdf.sample(wo, 0.999999f, 0.5f, 0.5f, out));  // u_lobe above F: refraction
      ++refracted;
      ASSERT_TRUE(out.specular);
      ASSERT_LT(out.wi.z * wo.z, 0.f) << "refracted ray on the incident side";
      ASSERT_NEAR(length(out.wi), 1.f, 1e-5f);
      // Snell: sin_t = sin_i / eta, in the plane of incidence on the other side of the normal.
      ASSERT_NEAR(out.wi.x, -wo.x / eta, 2e-6);
      ASSERT_NEAR(out.wi.y, -wo.y / eta, 2e-6);
      const double sin_t = std::sqrt(double(out.wi.x) * out.wi.x + double(out.wi.y) * out.wi.y);
      ASSERT_NEAR(sin_t, sin_i / eta, 2e-6);
      // Radiance transport: the weight is tint * (eta_i / eta_t)^2.
      for (int c = 0; c < 3; ++c)
        ASSERT_TRUE(near_relative(out.weight[c], tint[c] / (eta * eta), 1e-6)) << out.weight[c];
    }
    EXPECT_GT(refracted, 200);  // from inside diamond only a cone of 24.6 degrees refracts
  }
}

TEST(DielectricTest, ReflectedFractionIsTheFresnelReflectance) {
  // Over N uniform u_lobe, the reflected count is binomial(N, F): z test.
  constexpr int kDraws = 100000;
  Pcg32 rng(91, 1);
  for (const DielectricCase& dc : kDielectricCases) {
    const Material glass = dielectric(dc.ior);
    const Bsdf bsdf(glass);
    const double eta = dc.side > 0 ? dc.ior : 1.0 / dc.ior;
    for (const double theta_deg : kFresnelThetaDeg) {
      SCOPED_TRACE(glass.name + (dc.side > 0 ? " from outside" : " from inside") + ", theta " +
                   std::to_string(theta_deg));
      const Vec3 wo = spherical(theta_deg * kDegree, 2.0, dc.side);
      const double f = fresnel_reference(std::fabs(double(wo.z)), eta);
      int reflected = 0;
      for (int k = 0; k < kDraws; ++k) {
        BsdfSample out;
        ASSERT_TRUE(draw(bsdf, wo, rng, out));
        if (out.wi.z * wo.z > 0.f) {
          ++reflected;
          ASSERT_EQ(out.wi, Vec3(-wo.x, -wo.y, wo.z));
          ASSERT_EQ(out.weight, Vec3(1.f));
        }
      }
      const double tolerance = kZ * std::sqrt(f * (1.0 - f) / kDraws) + 1e-5;
      EXPECT_NEAR(double(reflected) / kDraws, f, tolerance);
    }
  }
}

}  // namespace
}  // namespace rayfarm
