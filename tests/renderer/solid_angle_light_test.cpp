// Sampling of spheres and triangles by solid angle (renderer/lights/sphere_light.h,
// triangle_light.h, solid_angle.h): the density of sample() is what pdf() returns, on both sides
// of the switch between solid angle and area; the samples are uniform in the cone or spherical
// triangle; irradiance estimates match closed forms; degenerate views give no NaN.
//
// Statistics. Every Monte Carlo assertion is one two-sided z test, the family of all of them held
// at significance kAlpha = 0.01 by a Bonferroni correction (kHypotheses below). A histogram cell
// is binomial (standard error sqrt(p (1 - p) / N) from the expected p); a mean (irradiance, or
// the mean of 1 / pdf, whose expectation is the solid angle the light covers) has its standard
// error from the sample variance. Streams are Pcg32 with fixed seeds.
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/normal_quantile.h"
#include "renderer/lights/sphere_light.h"
#include "renderer/lights/triangle_light.h"
#include "renderer/samplers/rng.h"

namespace rayfarm {
namespace {

constexpr double kPiD = 3.141592653589793;

// Sphere: 2 histograms of 80 cells; 3 irradiances. Triangle: 5 views x (16 histogram cells, the
// mean of 1 / pdf, 1 irradiance).
constexpr int kHypotheses = 2 * 80 + 3 + 5 * (16 + 2);
const double kZ = testing::two_sided_z(0.01 / kHypotheses);
constexpr int kDraws = 400000;

double dot_d(const Vec3& a, const Vec3& b) {
  return double(a.x) * b.x + double(a.y) * b.y + double(a.z) * b.z;
}
Vec3 unit_d(const Vec3& a) {
  const double l = std::sqrt(dot_d(a, a));
  return {float(a.x / l), float(a.y / l), float(a.z / l)};
}

Material emitter(bool two_sided) {
  Material m;
  m.kind = DiffuseMaterial{Vec3(0.f)};
  m.emission = Vec3(1.f, 2.f, 3.f);
  m.two_sided = two_sided;
  return m;
}

Scene sphere_scene(const Vec3& center, float radius, bool two_sided) {
  Scene scene;
  scene.materials.push_back(emitter(two_sided));
  scene.spheres.push_back({center, radius, 0});
  return scene;
}

Scene triangle_scene(const Vec3& a, const Vec3& b, const Vec3& c, bool two_sided) {
  Scene scene;
  scene.materials.push_back(emitter(two_sided));
  TriangleMesh mesh;
  mesh.positions = {a, b, c};
  mesh.indices = {0, 1, 2};
  mesh.materials = {0};
  mesh.origin = "lamp";
  scene.meshes.push_back(mesh);
  return scene;
}

/// Binomial z tests of `counts` (of `draws`) against the probabilities `expected`.
void expect_histogram(const std::vector<int>& counts, const std::vector<double>& expected,
                      int draws, const std::string& what) {
  ASSERT_EQ(counts.size(), expected.size());
  for (size_t k = 0; k < counts.size(); ++k) {
    const double p = expected[k];
    EXPECT_NEAR(double(counts[k]) / draws, p, kZ * std::sqrt(p * (1.0 - p) / draws))
        << what << ": cell " << k;
  }
}

struct Mean {
  double sum = 0.0, sum2 = 0.0;
  void add(double x) { sum += x, sum2 += x * x; }
  double mean() const { return sum / kDraws; }
  double se() const {
    const double m = mean();
    return std::sqrt(std::max(0.0, sum2 / kDraws - m * m) / (kDraws - 1));
  }
};

/// Radiance and pdf are floats (relative rounding 6e-8 each): an estimator of almost no variance
/// keeps that rounding as a bias its standard error does not show; 1e-6 of the value allows it.
void expect_mean(const Mean& m, double expected, const std::string& what) {
  EXPECT_NEAR(m.mean(), expected, kZ * m.se() + 1e-6 * std::fabs(expected))
      << what << ", standard error " << m.se();
}

// ----------------------------------------------------------------------------------------------
// Spheres

/// From outside, the directions fill the cone uniformly: 1 - cos(theta) over 1 - cos(theta_max)
/// in 10 cells, the azimuth about the axis in 8. Also pdf() of every point equals its sample's.
void check_cone(const Vec3& center, float radius, const Vec3& ref, uint64_t seed) {
  const Scene scene = sphere_scene(center, radius, false);
  const auto light = SphereLight::make(scene, 0);
  ASSERT_TRUE(light);
  const double d = std::sqrt(dot_d(center - ref, center - ref)), r = radius;
  const double omc = (r / d) * (r / d) / (1.0 + std::sqrt(1.0 - (r / d) * (r / d)));
  const Vec3 w = unit_d(center - ref);
  const Vec3 e1 =
      unit_d(std::fabs(w.x) > 0.5f ? cross(w, Vec3(0.f, 1.f, 0.f)) : cross(w, Vec3(1.f, 0.f, 0.f)));
  const Vec3 e2 = cross(w, e1);
  std::vector<int> counts(80, 0);
  int failed = 0, mismatched = 0;
  Pcg32 rng(seed, 3);
  for (int k = 0; k < kDraws; ++k) {
    const float u1 = rng.next_float(), u2 = rng.next_float();
    LightSample out;
    if (!light->sample(ref, 1.f, u1, u2, out)) {
      ++failed;
      continue;
    }
    // The point drawn (target before its offset), and its normal.
    const Vec3 n = unit_d(out.target - center);
    const Vec3 p = center + n * radius;
    const float pdf = light->pdf(1.f, ref, p, n);
    if (std::fabs(pdf - out.pdf) > 1e-6f * out.pdf) ++mismatched;
    // 1 - cos from the cross product (accurate for narrow cones).
    const Vec3 c = cross(w, out.wi);
    const double sin2 = dot_d(c, c);
    const double one_minus_cos = sin2 / (1.0 + std::sqrt(std::max(0.0, 1.0 - sin2)));
    const int ci = std::min(9, int(10.0 * one_minus_cos / omc));
    double phi = std::atan2(dot_d(out.wi, e2), dot_d(out.wi, e1));
    if (phi < 0.0) phi += 2.0 * kPiD;
    const int pi = std::min(7, int(8.0 * phi / (2.0 * kPiD)));
    ++counts[ci * 8 + pi];
  }
  EXPECT_EQ(failed, 0);
  EXPECT_EQ(mismatched, 0);
  expect_histogram(counts, std::vector<double>(80, 1.0 / 80), kDraws, "cone cells");
}

TEST(SphereSolidAngleTest, NearSphereFillsItsConeUniformly) {
  check_cone({0.3f, -0.2f, 0.4f}, 1.f, {0.5f, 0.9f, 2.1f}, 11);  // d / r ~ 2
}

TEST(SphereSolidAngleTest, FarSphereFillsItsConeUniformly) {
  check_cone({0.f, 0.f, 0.f}, 1e-3f, {3.f, 2.f, -1.f}, 12);  // r / d ~ 3e-4
}

/// The estimate of the irradiance at ref (normal facing the centre) from a one-sided sphere.
Mean sphere_irradiance(float radius, float distance, uint64_t seed) {
  const Scene scene = sphere_scene({0.f, 0.f, 0.f}, radius, false);
  const auto light = SphereLight::make(scene, 0);
  const Vec3 ref(0.f, distance, 0.f), normal(0.f, -1.f, 0.f);
  Mean m;
  Pcg32 rng(seed, 5);
  for (int k = 0; k < kDraws; ++k) {
    const float u1 = rng.next_float(), u2 = rng.next_float();
    LightSample out;
    if (light && light->sample(ref, 1.f, u1, u2, out))
      m.add(out.radiance.y * std::max(0.0, dot_d(normal, out.wi)) / out.pdf);
    else
      m.add(0.0);
  }
  return m;
}

TEST(SphereSolidAngleTest, IrradianceAtNormalIncidenceIsPiLRSquaredOverDSquared) {
  // pi L (r / d)^2 (L = 2 in green), from near to so far that 1 - cos(theta_max) = 5e-15 would be
  // lost to cancellation in 1 - sqrt(1 - (r / d)^2).
  for (const auto& [r, d, seed] :
       {std::tuple{1.f, 1.5f, 21}, std::tuple{0.1f, 10.f, 22}, std::tuple{1e-5f, 100.f, 23}}) {
    const double expected = kPiD * 2.0 * (double(r) / d) * (double(r) / d);
    expect_mean(sphere_irradiance(r, d, seed), expected, "r " + std::to_string(r));
  }
}

TEST(SphereSolidAngleTest, PointsOnOrInsideAreSampledByAreaConsistently) {
  // On the surface (within rounding) and inside, sampling is by area: every sample's pdf is
  // pdf() of its point, and nothing is NaN.
  const Vec3 center(1.f, 2.f, 3.f);
  const Scene scene = sphere_scene(center, 2.f, true);
  const auto light = SphereLight::make(scene, 0);
  ASSERT_TRUE(light);
  solid_angle::SphereCone cone;
  for (const Vec3& ref : {center, center + Vec3(0.f, 2.f, 0.f), center + Vec3(1.2f, 0.f, 1.6f),
                          center + Vec3(0.f, 0.f, -1.f)}) {
    EXPECT_FALSE(light->visible_cone(ref, cone));
    Pcg32 rng(31, 1);
    for (int k = 0; k < 10000; ++k) {
      const float u1 = rng.next_float(), u2 = rng.next_float();
      LightSample out;
      if (!light->sample(ref, 1.f, u1, u2, out)) continue;
      ASSERT_TRUE(std::isfinite(out.pdf) && out.pdf > 0.f);
      const Vec3 n = unit_d(out.target - center);
      const float pdf = light->pdf(1.f, ref, center + n * 2.f, n);
      ASSERT_NEAR(pdf, out.pdf, 1e-3f * out.pdf + 1e-6f);
    }
  }
  // Just outside: by the cone.
  EXPECT_TRUE(light->visible_cone(center + Vec3(0.f, 2.01f, 0.f), cone));
}

// ----------------------------------------------------------------------------------------------
// Triangles

/// Solid angle of the triangle (a, b, c) seen from ref, by L'Huilier's theorem from the arcs of
/// its sides (a route apart from the light's).
double lhuilier(const Vec3& ref, const Vec3& a, const Vec3& b, const Vec3& c) {
  using solid_angle::unit;
  const WideVec3 r = wide(ref);
  const WideVec3 u = unit(wide(a) - r), v = unit(wide(b) - r), w = unit(wide(c) - r);
  const auto arc = [](const WideVec3& x, const WideVec3& y) {
    return 2.0 * std::atan2(length(x - y), length(solid_angle::add(x, y)));
  };
  const double sa = arc(v, w), sb = arc(w, u), sc = arc(u, v), s = 0.5 * (sa + sb + sc);
  const double t = std::tan(0.5 * s) * std::tan(0.5 * (s - sa)) * std::tan(0.5 * (s - sb)) *
                   std::tan(0.5 * (s - sc));
  return 4.0 * std::atan(std::sqrt(std::max(0.0, t)));
}

/// Irradiance on the plane through ref with unit normal `normal` from a triangle of radiance L
/// wholly above that plane (Lambert's polygon formula: half the sum over the edges of the arc
/// times the cosine of the edge plane's normal).
double lambert_irradiance(const Vec3& ref, const Vec3& normal, const Vec3 (&v)[3], double l) {
  double sum = 0.0;
  for (int i = 0; i < 3; ++i) {
    const Vec3 a = unit_d(v[i] - ref), b = unit_d(v[(i + 1) % 3] - ref);
    const double arc = std::acos(std::clamp(dot_d(a, b), -1.0, 1.0));
    sum += arc * dot_d(unit_d(cross(a, b)), normal);
  }
  return 0.5 * l * std::fabs(sum);
}

struct TriangleView {
  const char* name;
  Vec3 ref;
  bool spherical;  // expected strategy
};

/// The triangle of these views, and four points seen from which it subtends solid angles on
/// both sides of the lower switch and in the middle of the band.
const Vec3 kTri[3] = {{-1.f, 0.f, -1.f}, {0.2f, 0.f, 1.3f}, {1.5f, 0.f, -0.8f}};

void check_triangle_view(const TriangleView& view, uint64_t seed) {
  const Scene scene = triangle_scene(kTri[0], kTri[1], kTri[2], false);
  const auto light = TriangleLight::make(scene, 0, 0);
  ASSERT_TRUE(light);
  const Vec3 n(0.f, 1.f, 0.f);  // the front side of (a, b, c)
  const double omega = lhuilier(view.ref, kTri[0], kTri[1], kTri[2]);
  TriangleLight::SphericalView sv;
  ASSERT_EQ(light->spherical_view(view.ref, light->height_above(view.ref), sv), view.spherical)
      << view.name << " " << omega;
  // Both in double; L'Huilier's product of tangents is the less well conditioned near 2 pi.
  if (view.spherical) {
    EXPECT_NEAR(sv.area, omega, 1e-8 * omega) << view.name;
  }
  // 16 cells: the triangle cut by the lattice of barycentrics in quarters. A cell's probability
  // is its share of the solid angle (by solid angle) or of the area (by area).
  constexpr int kCut = 4;
  std::vector<double> expected;
  std::vector<std::array<Vec3, 3>> cells;
  const auto at = [](double b1, double b2) {
    return kTri[0] * float(1.0 - b1 - b2) + kTri[1] * float(b1) + kTri[2] * float(b2);
  };
  for (int i = 0; i < kCut; ++i) {
    for (int j = 0; i + j < kCut; ++j) {
      const double s = 1.0 / kCut;
      cells.push_back({at(i * s, j * s), at((i + 1) * s, j * s), at(i * s, (j + 1) * s)});
      if (i + j + 1 < kCut)
        cells.push_back(
            {at((i + 1) * s, j * s), at((i + 1) * s, (j + 1) * s), at(i * s, (j + 1) * s)});
    }
  }
  for (const auto& c : cells)
    expected.push_back(view.spherical ? lhuilier(view.ref, c[0], c[1], c[2]) / omega
                                      : 1.0 / (kCut * kCut));
  std::vector<int> counts(cells.size(), 0);
  Mean inverse_pdf, irradiance;
  const Vec3 normal(0.f, -1.f, 0.f);  // the triangle wholly above the receiver's horizon
  int mismatched = 0, off_ray = 0;
  Pcg32 rng(seed, 7);
  for (int k = 0; k < kDraws; ++k) {
    const float u1 = rng.next_float(), u2 = rng.next_float();
    LightSample out;
    float b[3] = {-1.f, -1.f, -1.f};
    const bool ok =
        light->sample_with(view.ref, 1.f, u1, u2, out, [&](float b0, float b1, float b2) {
          b[0] = b0, b[1] = b1, b[2] = b2;
          return Vec3(1.f, 2.f, 3.f);
        });
    if (!ok) {
      inverse_pdf.add(0.0), irradiance.add(0.0);
      continue;
    }
    // The barycentrics name the point the direction meets.
    const Vec3 p = kTri[0] * b[0] + kTri[1] * b[1] + kTri[2] * b[2];
    const Vec3 off = cross(unit_d(p - view.ref), out.wi);
    if (std::sqrt(dot_d(off, off)) > 1e-5) ++off_ray;
    const float pdf = light->pdf(1.f, view.ref, p, n);
    if (std::fabs(pdf - out.pdf) > 1e-4f * out.pdf) ++mismatched;
    inverse_pdf.add(1.0 / pdf);
    irradiance.add(out.radiance.y * std::max(0.0, dot_d(normal, out.wi)) / out.pdf);
    // The cell: the lattice square (i, j), its lower or upper half.
    const double x = b[1] * kCut, y = b[2] * kCut;
    const int i = std::min(kCut - 1, int(x)), j = std::min(kCut - 1 - i, int(y));
    const bool upper = (x - i) + (y - j) > 1.0 && i + j + 1 < kCut;
    int index = 0;
    for (int ii = 0; ii < i; ++ii) index += 2 * (kCut - ii) - 1;
    index += 2 * j + (upper ? 1 : 0);
    ++counts[index];
  }
  EXPECT_EQ(mismatched, 0) << view.name;
  EXPECT_EQ(off_ray, 0) << view.name;
  expect_histogram(counts, expected, kDraws, view.name);
  // E[1 / pdf] is the solid angle the samples can reach, whichever the strategy.
  expect_mean(inverse_pdf, omega, std::string(view.name) + ": mean of 1 / pdf");
  expect_mean(irradiance, lambert_irradiance(view.ref, normal, kTri, 2.0),
              std::string(view.name) + ": irradiance");
}

TEST(TriangleSolidAngleTest, DensityMatchesPdfOnBothSidesOfTheSwitch) {
  // Points above the centroid where the solid angle falls just below (0.247 sr) and just above
  // (0.262) the lower bound of 0.25, one so far (0.01) that a bound decides without the
  // spherical triangle,
  // one beside a corner (0.32) and one just above the inside (5.92, near the upper bound).
  const Vec3 centroid = (kTri[0] + kTri[1] + kTri[2]) * (1.f / 3.f);
  const TriangleView views[] = {{"far, by area", centroid + Vec3(0.3f, 3.2f, 0.1f), false},
                                {"just near enough", centroid + Vec3(0.3f, 3.1f, 0.1f), true},
                                {"very far", centroid + Vec3(0.3f, 16.f, 0.1f), false},
                                {"beside a corner", {1.6f, 0.1f, -0.9f}, true},
                                {"just above the inside", {0.3f, 0.05f, 0.f}, true}};
  uint64_t seed = 41;
  for (const TriangleView& v : views) check_triangle_view(v, seed++);
}

TEST(TriangleSolidAngleTest, CornersInOppositeDirectionsAreSampledByArea) {
  // A huge triangle whose diagonal passes just above the point: its two ends lie in opposite
  // directions to within 1e-14, where the edge's great circle is left to rounding (the point's
  // offset of 0.3 from the diagonal is below a double's resolution at 6e16). It subtends ~pi,
  // inside the band, yet must be sampled by area.
  const float h = 6e16f;
  const Scene scene =
      triangle_scene({-h, 1e3f, -h}, {h, 1e3f, -h}, {h, 1e3f, h}, false);  // faces down
  const auto light = TriangleLight::make(scene, 0, 0);
  ASSERT_TRUE(light);
  const Vec3 ref(0.3f, 0.5f, -0.2f);
  TriangleLight::SphericalView view;
  EXPECT_GT(light->height_above(ref), 0.0);
  EXPECT_FALSE(light->spherical_view(ref, light->height_above(ref), view));
  // The same view of a triangle as wide as it is far keeps its corners apart: by solid angle.
  const Scene small =
      triangle_scene({-1e3f, 1e3f, -1e3f}, {1e3f, 1e3f, -1e3f}, {1e3f, 1e3f, 1e3f}, false);
  const auto near = TriangleLight::make(small, 0, 0);
  ASSERT_TRUE(near);
  EXPECT_TRUE(near->spherical_view(ref, near->height_above(ref), view));
}

TEST(TriangleSolidAngleTest, DegenerateViewsGiveNoNaN) {
  struct Case {
    const char* name;
    Vec3 a, b, c, ref;
  };
  const Case cases[] = {
      {"sliver", {0.f, 0.f, 0.f}, {1.f, 0.f, 0.f}, {0.5f, 0.f, 1e-6f}, {0.5f, 0.1f, 0.f}},
      {"tiny and near", {0.f, 0.f, 0.f}, {1e-6f, 0.f, 0.f}, {0.f, 0.f, 1e-6f}, {0.f, 1e-6f, 0.f}},
      {"tiny and far", {0.f, 0.f, 0.f}, {1e-6f, 0.f, 0.f}, {0.f, 0.f, 1e-6f}, {3.f, 100.f, 0.f}},
      {"huge, point just above",
       {-1e6f, 0.f, -1e6f},
       {1e6f, 0.f, -1e6f},
       {0.f, 0.f, 1e6f},
       {0.f, 1e-3f, 0.f}},
      {"huge, point far above",
       {-1e6f, 0.f, -1e6f},
       {1e6f, 0.f, -1e6f},
       {0.f, 0.f, 1e6f},
       {0.f, 1e5f, 0.f}},
      {"point in its plane", {0.f, 0.f, 0.f}, {1.f, 0.f, 0.f}, {0.f, 0.f, 1.f}, {2.f, 0.f, 2.f}},
      {"point on a vertex", {0.f, 0.f, 0.f}, {1.f, 0.f, 0.f}, {0.f, 0.f, 1.f}, {0.f, 0.f, 0.f}},
      {"point on an edge, above",
       {0.f, 0.f, 0.f},
       {1.f, 0.f, 0.f},
       {0.f, 0.f, 1.f},
       {0.5f, 1e-7f, 0.f}},
  };
  for (const Case& c : cases) {
    const Scene scene = triangle_scene(c.a, c.c, c.b, true);  // (a, c, b): front side +y
    const auto light = TriangleLight::make(scene, 0, 0);
    if (!light) continue;  // no area in float: not a light at all
    Pcg32 rng(51, 1);
    int nonfinite = 0, mismatched = 0;
    for (int k = 0; k < 20000; ++k) {
      const float u1 = rng.next_float(), u2 = rng.next_float();
      LightSample out;
      float b[3] = {};
      if (!light->sample_with(c.ref, 1.f, u1, u2, out, [&](float b0, float b1, float b2) {
            b[0] = b0, b[1] = b1, b[2] = b2;
            return Vec3(1.f);
          }))
        continue;
      const bool finite = std::isfinite(out.pdf) && out.pdf > 0.f &&
                          std::isfinite(dot_d(out.wi, out.wi)) &&
                          std::fabs(dot_d(out.wi, out.wi) - 1.0) < 1e-5 &&
                          std::isfinite(dot_d(out.target, out.target)) && b[0] >= -1e-6f &&
                          b[1] >= 0.f && b[2] >= 0.f;
      if (!finite) {
        ++nonfinite;
        continue;
      }
      const Vec3 p = c.a * b[0] + c.c * b[1] + c.b * b[2];
      const float pdf = light->pdf(1.f, c.ref, p, Vec3(0.f, 1.f, 0.f));
      if (!(std::fabs(pdf - out.pdf) <= 1e-3f * out.pdf)) ++mismatched;
    }
    EXPECT_EQ(nonfinite, 0) << c.name;
    EXPECT_EQ(mismatched, 0) << c.name;
  }
}

}  // namespace
}  // namespace rayfarm
