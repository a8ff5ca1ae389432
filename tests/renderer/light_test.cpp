// The light sampler (renderer/lights/light_set.h) on hand-built scenes: an emissive square (two
// triangles), an emissive sphere and a point light, with a non-emissive square that must be left
// out. Selection follows power, the returned pdf is the pdf of the chosen point (by solid angle
// for the sphere seen from outside and for the square's triangles where they look large, else by
// area), the estimate of the irradiance converges to its analytic value, one-sided emitters are
// dark behind.
//
// Statistics. Every Monte Carlo assertion is one two-sided z test; the family of all of them in
// this file is held at significance kAlpha = 0.01 by a Bonferroni correction, so each uses the
// threshold z with P(|Z| > z) = kAlpha / kHypotheses (z = 3.5 here). A selection frequency is
// binomial (standard error sqrt(p (1 - p) / N) from the expected p); an irradiance estimate is a
// sample mean (standard error from the sample variance). Every stream is a Pcg32 with a fixed
// seed, so each run draws the same numbers.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "common/math/vec3.h"
#include "common/scene/scene.h"
#include "tests/support/normal_quantile.h"
#include "renderer/lights/light_set.h"
#include "renderer/samplers/rng.h"
#include "renderer/scene_data.h"

namespace rayfarm {
namespace {

constexpr double kPiD = 3.141592653589793;

using testing::two_sided_z;

// The hypothesis tests of this file: selection frequencies of 4 lights in 2 scenes, and 7
// irradiance estimates of 3 channels each.
constexpr int kHypotheses = 2 * 4 + 7 * 3;
constexpr double kAlpha = 0.01;
const double kZ = two_sided_z(kAlpha / kHypotheses);

double luminance_d(const Vec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }
double dot_d(const Vec3& a, const Vec3& b) {
  return double(a.x) * b.x + double(a.y) * b.y + double(a.z) * b.z;
}
double distance_d(const Vec3& a, const Vec3& b) {
  const Vec3 d = a - b;
  return std::sqrt(dot_d(d, d));
}

// ----------------------------------------------------------------------------------------------
// Scenes

/// What a test scene holds. The square lies in z = 0, centred on the origin, front face +z.
struct SceneSpec {
  bool with_square = true;
  float square_half = 1.f;
  Vec3 square_emission{1.f, 2.f, 3.f};
  bool square_two_sided = false;

  bool with_sphere = true;
  Vec3 sphere_center{3.f, 0.f, 0.5f};
  float sphere_radius = 0.5f;
  Vec3 sphere_emission{4.f, 4.f, 4.f};
  bool sphere_two_sided = true;

  bool with_point = true;
  Vec3 point_position{-1.f, 1.f, 0.5f};
  Vec3 point_intensity{2.f, 1.f, 0.5f};

  bool with_floor = true;  // a non-emissive square far below, which is no light

  // Expected powers: luminance * area * pi (x 2 when two-sided); 4 pi luminance for a point.
  double triangle_power() const {  // each of the square's two triangles
    if (!with_square) return 0.0;
    const double area = 2.0 * square_half * square_half;
    return luminance_d(square_emission) * area * kPiD * (square_two_sided ? 2.0 : 1.0);
  }
  double sphere_area() const { return 4.0 * kPiD * sphere_radius * sphere_radius; }
  double sphere_power() const {
    if (!with_sphere) return 0.0;
    return luminance_d(sphere_emission) * sphere_area() * kPiD * (sphere_two_sided ? 2.0 : 1.0);
  }
  double point_power() const {
    return with_point ? 4.0 * kPiD * luminance_d(point_intensity) : 0.0;
  }
  double total_power() const { return 2.0 * triangle_power() + sphere_power() + point_power(); }
};

Material emitter(const std::string& name, const Vec3& emission, bool two_sided) {
  Material m;
  m.name = name;
  m.kind = DiffuseMaterial{Vec3(0.f)};
  m.emission = emission;
  m.two_sided = two_sided;
  return m;
}

/// A square of half-side `half` in the plane z = `z`, facing +z: triangles (0, 1, 2), (0, 2, 3).
TriangleMesh square(float half, float z, uint32_t material, const std::string& origin) {
  TriangleMesh mesh;
  mesh.positions = {{-half, -half, z}, {half, -half, z}, {half, half, z}, {-half, half, z}};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  mesh.materials = {material, material};
  mesh.origin = origin;
  return mesh;
}

Scene build_scene(const SceneSpec& s) {
  Scene scene;
  scene.film = {16, 16};
  Material grey;
  grey.name = "grey";
  scene.materials.push_back(grey);
  if (s.with_floor) scene.meshes.push_back(square(10.f, -5.f, 0, "floor"));
  if (s.with_square) {
    scene.materials.push_back(emitter("square", s.square_emission, s.square_two_sided));
    scene.meshes.push_back(
        square(s.square_half, 0.f, uint32_t(scene.materials.size() - 1), "lamp"));
  }
  if (s.with_sphere) {
    scene.materials.push_back(emitter("sphere", s.sphere_emission, s.sphere_two_sided));
    scene.spheres.push_back(
        {s.sphere_center, s.sphere_radius, uint32_t(scene.materials.size() - 1)});
  }
  if (s.with_point) scene.point_lights.push_back({s.point_position, s.point_intensity});
  return scene;
}

/// A scene ready for sampling: the SceneData must outlive the LightSet that points into it.
/// Lights are chosen by power (these tests check its frequencies; light_tree_test.cpp the tree).
struct Lights {
  explicit Lights(const SceneSpec& s)
      : setup(s), data(build_scene(s)), set(data, LightChoice::kPower) {}
  SceneSpec setup;
  SceneData data;
  LightSet set;

  /// Light index registered for the primitive that a ray from `org` along `dir` hits first.
  int32_t light_hit_by(const Vec3& org, const Vec3& dir) const {
    const Ray ray{org, dir};
    const std::optional<RayHit> hit = data.bvh().intersect(ray);
    if (!hit) return -2;
    return data.resolve(ray, *hit).light;
  }
  int32_t triangle_light(int t) const {
    const float h = 0.5f * setup.square_half;
    return t == 0 ? light_hit_by({h, -h, 5.f}, {0.f, 0.f, -1.f})
                  : light_hit_by({-h, h, 5.f}, {0.f, 0.f, -1.f});
  }
  int32_t sphere_light() const {
    return light_hit_by(setup.sphere_center + Vec3(0.f, 0.f, 5.f), {0.f, 0.f, -1.f});
  }
};

/// Draws one light sample with three numbers from rng, in a fixed order.
bool draw(const LightSet& lights, const Vec3& ref, Pcg32& rng, LightSample& out) {
  const float u_select = rng.next_float();
  const float u1 = rng.next_float();
  const float u2 = rng.next_float();
  return lights.sample(ref, Vec3(0.f), SelectionNumber::from_float(u_select), u1, u2, out);
}

enum Chosen { kTriangle0, kTriangle1, kSphereLight, kPointLight, kFailed, kUnknown };

/// Which light a successful sample came from: delta for the point light, else where its target
/// lies (in the square's plane, below or above its diagonal y = x; or on the sphere).
Chosen classify(const SceneSpec& s, bool ok, const LightSample& out) {
  if (!ok) return kFailed;
  if (out.delta) return kPointLight;
  if (s.with_square && std::fabs(out.target.z) < 1e-4f &&
      std::fabs(out.target.x) <= s.square_half && std::fabs(out.target.y) <= s.square_half)
    return out.target.y <= out.target.x ? kTriangle0 : kTriangle1;
  if (s.with_sphere && std::fabs(distance_d(out.target, s.sphere_center) - s.sphere_radius) < 1e-4)
    return kSphereLight;
  return kUnknown;
}

/// The point the sample chose and the light's normal there: where the ray from ref along wi
/// meets the chosen light, taking the intersection nearest to the sample's target.
void chosen_point(const SceneSpec& s, Chosen chosen, const Vec3& ref, const LightSample& out,
                  Vec3& p, Vec3& n) {
  const double w[3] = {out.wi.x, out.wi.y, out.wi.z};
  const double o[3] = {ref.x, ref.y, ref.z};
  double t = 0.0;
  if (chosen == kSphereLight) {
    const double oc[3] = {o[0] - s.sphere_center.x, o[1] - s.sphere_center.y,
                          o[2] - s.sphere_center.z};
    const double ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    const double b = (w[0] * oc[0] + w[1] * oc[1] + w[2] * oc[2]) / ww;
    const double r2 = double(s.sphere_radius) * s.sphere_radius;
    const double c = (oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - r2) / ww;
    const double root = std::sqrt(std::max(0.0, b * b - c));
    const double target_t = distance_d(out.target, ref) / std::sqrt(ww);
    const double t0 = -b - root, t1 = -b + root;
    t = std::fabs(t0 - target_t) < std::fabs(t1 - target_t) ? t0 : t1;
  } else {
    t = -o[2] / w[2];  // the plane z = 0
  }
  const double pd[3] = {o[0] + t * w[0], o[1] + t * w[1], o[2] + t * w[2]};
  p = Vec3(float(pd[0]), float(pd[1]), float(pd[2]));
  if (chosen == kSphereLight) {
    const double r = s.sphere_radius;
    n = Vec3(float((pd[0] - s.sphere_center.x) / r), float((pd[1] - s.sphere_center.y) / r),
             float((pd[2] - s.sphere_center.z) / r));
  } else {
    n = Vec3(0.f, 0.f, 1.f);
  }
}

/// Solid angle of the triangle (a, b, c) seen from ref, from its interior angles (Girard's
/// theorem: the excess of their sum over pi), a route apart from the light's own formula.
double girard_solid_angle(const Vec3& ref, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 v[3] = {normalize(a - ref), normalize(b - ref), normalize(c - ref)};
  double sum = 0.0;
  for (int i = 0; i < 3; ++i) {
    const Vec3 &p = v[i], &q = v[(i + 1) % 3], &r = v[(i + 2) % 3];
    // Tangents at p towards q and towards r; the interior angle lies between them.
    const Vec3 tq = normalize(q - p * float(dot_d(p, q))),
               tr = normalize(r - p * float(dot_d(p, r)));
    sum += std::acos(std::clamp(dot_d(tq, tr), -1.0, 1.0));
  }
  return sum - kPiD;
}

/// The density, selection excluded, that the light drawn as `chosen` has for the point p (normal
/// n) seen from ref: uniform in the visible cone for a sphere seen from outside, uniform in the
/// spherical triangle for a triangle within the light's band of solid angles, else uniform by
/// area (dist^2 / (cos area)).
double analytic_density(const SceneSpec& s, Chosen chosen, const Vec3& ref, const Vec3& p,
                        const Vec3& n) {
  const double dist = distance_d(p, ref);
  const double cos_light = std::fabs(dot_d(n, normalize(p - ref)));
  if (chosen == kSphereLight) {
    const double d = distance_d(ref, s.sphere_center), r = s.sphere_radius;
    if (d > 1.01 * r) return 1.0 / (2.0 * kPiD * (1.0 - std::sqrt(1.0 - r * r / (d * d))));
    return dist * dist / (cos_light * s.sphere_area());
  }
  const float h = s.square_half;
  const Vec3 a{-h, -h, 0.f}, c{h, h, 0.f};
  const Vec3 b = chosen == kTriangle0 ? Vec3{h, -h, 0.f} : Vec3{-h, h, 0.f};
  const double omega = girard_solid_angle(ref, a, b, c);
  if (omega >= TriangleLight::kMinSolidAngle && omega <= TriangleLight::kMaxSolidAngle)
    return 1.0 / omega;
  return dist * dist / (cos_light * h * h * 2.0);
}

bool near_relative(double a, double b, double rel) {
  return std::fabs(a - b) <= rel * std::max(std::fabs(a), std::fabs(b));
}

/// Failed per-sample checks: counted, the first one described, so that a broken sampler is
/// reported once rather than once per sample.
struct Mismatches {
  int count = 0;
  std::string first;
  void add(const char* what, double got, double expected) {
    if (count++ == 0)
      first = std::string(what) + ": " + std::to_string(got) + " vs " + std::to_string(expected);
  }
};

// ----------------------------------------------------------------------------------------------
// Structure

TEST(LightSetTest, CollectsEmittersAndRegistersTheirIndices) {
  const Lights lights{SceneSpec{}};
  EXPECT_EQ(lights.set.size(), 4u);
  EXPECT_EQ(lights.set.area_light_count(), 3u);
  EXPECT_EQ(lights.set.point_light_count(), 1u);
  const int32_t t0 = lights.triangle_light(0), t1 = lights.triangle_light(1);
  const int32_t sphere = lights.sphere_light();
  for (const int32_t index : {t0, t1, sphere}) {
    EXPECT_GE(index, 0);
    EXPECT_LT(index, 4);
  }
  EXPECT_NE(t0, t1);
  EXPECT_NE(t0, sphere);
  EXPECT_NE(t1, sphere);
  EXPECT_EQ(lights.light_hit_by({8.f, 8.f, 0.f}, {0.f, 0.f, -1.f}), -1);  // the grey floor
  EXPECT_EQ(lights.set.pdf(-1, {0.f, 0.f, 2.f}, Vec3(0.f), {0.f, 0.f, 0.f}, {0.f, 0.f, 1.f}), 0.f);

  SceneSpec none;
  none.with_square = none.with_sphere = none.with_point = false;
  const Lights empty{none};
  EXPECT_TRUE(empty.set.empty());
  LightSample out;
  EXPECT_FALSE(
      empty.set.sample({0.f, 0.f, 1.f}, Vec3(0.f), SelectionNumber{1u << 31}, 0.5f, 0.5f, out));
}

// ----------------------------------------------------------------------------------------------
// Selection by power, and the pdf of the chosen point

/// Draws N samples from `ref`, checks each one (pdf against LightSet::pdf of the same point and
/// against the expected power fraction, radiance, direction), and tests the frequency with which
/// each light is chosen. Returns how often the sphere was chosen and how often its sample failed.
struct SphereDraws {
  int chosen = 0, failed = 0;
};
SphereDraws check_selection(const Lights& lights, const Vec3& ref, uint64_t seed) {
  constexpr int kDraws = 1000000;
  const SceneSpec& s = lights.setup;
  const double total = s.total_power();
  const std::array<double, 4> expected = {s.triangle_power() / total, s.triangle_power() / total,
                                          s.sphere_power() / total, s.point_power() / total};
  const std::array<int32_t, 3> index = {lights.triangle_light(0), lights.triangle_light(1),
                                        lights.sphere_light()};
  std::array<int, 6> counts{};
  Mismatches bad;
  Pcg32 rng(seed, 1);
  for (int k = 0; k < kDraws; ++k) {
    LightSample out;
    const bool ok = draw(lights.set, ref, rng, out);
    const Chosen chosen = classify(s, ok, out);
    ++counts[chosen];
    if (chosen == kFailed || chosen == kUnknown) continue;
    if (std::fabs(length(out.wi) - 1.f) > 1e-5f) bad.add("wi not unit", length(out.wi), 1.0);
    if (chosen == kPointLight) {
      if (!near_relative(out.pdf, expected[kPointLight], 1e-4))
        bad.add("point light pdf vs its selection probability", out.pdf, expected[kPointLight]);
      continue;
    }
    if (out.delta) bad.add("area light sample marked delta", 1, 0);
    const Vec3 emission = chosen == kSphereLight ? s.sphere_emission : s.square_emission;
    if (!(out.radiance == emission)) bad.add("radiance (green)", out.radiance.y, emission.y);
    Vec3 p, n;
    chosen_point(s, chosen, ref, out, p, n);
    const double cos_light = std::fabs(dot_d(n, out.wi));
    // p is rebuilt from the float direction wi: an error of ~2e-7 across a sphere's surface moves
    // the rebuilt point along the ray by ~2e-7 / cos, its normal by ~2e-7 / (r cos), and so
    // cos_light by a relative ~2e-7 / (r cos^2).
    if (distance_d(p, out.target) > 1e-5 + 1e-6 / cos_light)
      bad.add("target's distance to the chosen point", distance_d(p, out.target), 0.0);
    const double rel = 1e-4 + 1e-6 / (cos_light * cos_light);
    // The pdf of the chosen point, as the integrator computes it for a BSDF-sampled hit.
    const float pdf = lights.set.pdf(index[chosen], ref, Vec3(0.f), p, n);
    const double analytic = expected[chosen] * analytic_density(s, chosen, ref, p, n);
    if (!near_relative(out.pdf, pdf, rel)) bad.add("pdf vs LightSet::pdf", out.pdf, pdf);
    if (!near_relative(out.pdf, analytic, rel)) bad.add("pdf vs analytic", out.pdf, analytic);
  }
  EXPECT_EQ(bad.count, 0) << "first: " << bad.first;
  EXPECT_EQ(counts[kUnknown], 0);
  // Selection frequencies: a failed sample is charged to the sphere, the only light that can fail
  // in these scenes (its far side when one-sided).
  const std::array<int, 4> chosen = {counts[kTriangle0], counts[kTriangle1],
                                     counts[kSphereLight] + counts[kFailed], counts[kPointLight]};
  for (int l = 0; l < 4; ++l) {
    const double p = expected[l];
    EXPECT_NEAR(double(chosen[l]) / kDraws, p, kZ * std::sqrt(p * (1.0 - p) / kDraws))
        << "light " << l;
  }
  return {chosen[kSphereLight], counts[kFailed]};
}

TEST(LightSetTest, SelectsByPowerWithTwoSidedSphere) {
  // Square one-sided (the reference point is in front), sphere two-sided: nothing fails.
  const Lights lights{SceneSpec{}};
  EXPECT_EQ(check_selection(lights, {0.2f, -0.1f, 2.f}, 101).failed, 0);
}

TEST(LightSetTest, SelectsByPowerWithTwoSidedSquareSeenFromBehind) {
  SceneSpec s;
  s.square_two_sided = true;
  s.sphere_two_sided = false;
  s.sphere_center = {2.f, 1.f, -1.f};
  const Lights lights{s};
  const Vec3 ref{0.2f, -0.3f, -2.f};
  const SphereDraws sphere = check_selection(lights, ref, 102);
  // A one-sided sphere seen from outside is sampled within the cone that sees it: every point
  // lies on the lit cap. Only rounding at the silhouette (a fraction ~1e-7 of the cone) could
  // leave a point edge-on.
  ASSERT_GT(sphere.chosen, 0);
  EXPECT_LE(double(sphere.failed) / sphere.chosen, 1e-5);
}

// ----------------------------------------------------------------------------------------------
// Irradiance

/// Mean and standard error, per channel, of radiance * max(0, cos) / pdf over N samples (a
/// failed sample contributes 0): an unbiased estimate of the irradiance at (ref, normal).
struct Estimate {
  double mean[3] = {}, se[3] = {};
};

Estimate estimate_irradiance(const LightSet& lights, const Vec3& ref, const Vec3& normal,
                             uint64_t seed) {
  constexpr int kDraws = 1000000;
  double sum[3] = {}, sum2[3] = {};
  Pcg32 rng(seed, 1);
  for (int k = 0; k < kDraws; ++k) {
    LightSample out;
    if (!draw(lights, ref, rng, out)) continue;
    const double cos_ref = std::max(0.0, dot_d(normal, out.wi));
    for (int c = 0; c < 3; ++c) {
      const double x = out.radiance[c] * cos_ref / out.pdf;
      sum[c] += x;
      sum2[c] += x * x;
    }
  }
  Estimate e;
  for (int c = 0; c < 3; ++c) {
    e.mean[c] = sum[c] / kDraws;
    const double variance = std::max(0.0, sum2[c] / kDraws - e.mean[c] * e.mean[c]);
    e.se[c] = std::sqrt(variance / (kDraws - 1));
  }
  return e;
}

/// The z test of an irradiance estimate. Each sample's radiance and pdf are floats, rounded to a
/// relative 6e-8 each: an estimator of (almost) no variance, as inside a sphere, keeps that
/// rounding as a bias its standard error does not show, so 1e-6 of the value is allowed on top.
void expect_irradiance(const Estimate& e, const std::array<double, 3>& expected) {
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(e.mean[c], expected[c], kZ * e.se[c] + 1e-6 * std::fabs(expected[c]))
        << "channel " << c << ", standard error " << e.se[c];
  }
}

/// Irradiance on the axis of a uniformly emitting square of half-side a, at height h, facing it:
/// four corner rectangles, each with form factor (1 / 2 pi) 2 X / sqrt(1 + X^2) atan(X / sqrt(1 +
/// X^2)), X = a / h; E = pi L F.
double square_axis_irradiance(double radiance, double half, double height) {
  const double x = half / height, s = std::sqrt(1.0 + x * x);
  return 4.0 * radiance * (x / s) * std::atan(x / s);
}

/// Irradiance from a uniformly emitting sphere (radius r, distance d, wholly above the horizon,
/// at angle beta from the normal): pi L (r / d)^2 cos(beta), as from a point source.
double sphere_irradiance(double radiance, double r, double d, double cos_beta) {
  return kPiD * radiance * (r / d) * (r / d) * cos_beta;
}

SceneSpec square_only(bool two_sided) {
  SceneSpec s;
  s.with_sphere = s.with_point = false;
  s.square_half = 2.f;
  s.square_emission = {1.5f, 1.f, 0.5f};
  s.square_two_sided = two_sided;
  return s;
}

TEST(LightIrradianceTest, SquareOnItsAxisMatchesTheFormFactor) {
  const Lights lights{square_only(false)};
  const Estimate e = estimate_irradiance(lights.set, {0.f, 0.f, 1.f}, {0.f, 0.f, -1.f}, 201);
  const Vec3 l = lights.setup.square_emission;
  expect_irradiance(e,
                    {square_axis_irradiance(l.x, 2.0, 1.0), square_axis_irradiance(l.y, 2.0, 1.0),
                     square_axis_irradiance(l.z, 2.0, 1.0)});
}

TEST(LightIrradianceTest, TwoSidedSquareLightsItsBackAlike) {
  const Lights lights{square_only(true)};
  const Estimate e = estimate_irradiance(lights.set, {0.f, 0.f, -1.f}, {0.f, 0.f, 1.f}, 202);
  const Vec3 l = lights.setup.square_emission;
  expect_irradiance(e,
                    {square_axis_irradiance(l.x, 2.0, 1.0), square_axis_irradiance(l.y, 2.0, 1.0),
                     square_axis_irradiance(l.z, 2.0, 1.0)});
}

SceneSpec sphere_only(bool two_sided) {
  SceneSpec s;
  s.with_square = s.with_point = false;
  s.sphere_center = {0.f, 0.f, 0.f};
  s.sphere_radius = 0.5f;
  s.sphere_emission = {2.f, 3.f, 4.f};
  s.sphere_two_sided = two_sided;
  return s;
}

/// A receiver at distance 3 from the origin along (1, 2, 2) / 3, its normal turned from the
/// sphere's centre by beta with cos(beta) = 0.8 (the sphere's half-angle is asin(1/6) = 9.6 deg).
void sphere_receiver(Vec3& ref, Vec3& normal) {
  const Vec3 dir(1.f / 3.f, 2.f / 3.f, 2.f / 3.f);
  const Vec3 side(2.f / 3.f, 1.f / 3.f, -2.f / 3.f);  // unit, orthogonal to dir
  ref = dir * 3.f;
  normal = normalize(-dir * 0.8f + side * 0.6f);
}

TEST(LightIrradianceTest, SphereMatchesPointSourceLaw) {
  // One-sided: sampling in the cone that sees the sphere draws only its lit cap: pi L (r/d)^2.
  const Lights lights{sphere_only(false)};
  Vec3 ref, normal;
  sphere_receiver(ref, normal);
  const Estimate e = estimate_irradiance(lights.set, ref, normal, 203);
  const Vec3 l = lights.setup.sphere_emission;
  const double cos_beta = 0.8;
  expect_irradiance(
      e, {sphere_irradiance(l.x, 0.5, 3.0, cos_beta), sphere_irradiance(l.y, 0.5, 3.0, cos_beta),
          sphere_irradiance(l.z, 0.5, 3.0, cos_beta)});
}

TEST(LightIrradianceTest, TwoSidedSphereSeenFromOutsideShowsItsCapOnly) {
  // Two-sided: the inner side of the far half is hidden behind the near cap, and sampling within
  // the visible cone never draws it: the estimate equals the one-sided one.
  const Lights lights{sphere_only(true)};
  Vec3 ref, normal;
  sphere_receiver(ref, normal);
  const Estimate e = estimate_irradiance(lights.set, ref, normal, 204);
  const Vec3 l = lights.setup.sphere_emission;
  const double cos_beta = 0.8;
  expect_irradiance(
      e, {sphere_irradiance(l.x, 0.5, 3.0, cos_beta), sphere_irradiance(l.y, 0.5, 3.0, cos_beta),
          sphere_irradiance(l.z, 0.5, 3.0, cos_beta)});
}

TEST(LightIrradianceTest, TwoSidedSphereLightsItsInsideEvenly) {
  // Inside (and on) a sphere of uniform radiance L every direction sees L: E = pi L on any plane.
  // Sampling there is by area over the whole sphere.
  const Lights lights{sphere_only(true)};
  const Vec3 l = lights.setup.sphere_emission;
  const std::array<double, 3> expected = {kPiD * l.x, kPiD * l.y, kPiD * l.z};
  expect_irradiance(
      estimate_irradiance(lights.set, {0.1f, -0.2f, 0.15f}, normalize(Vec3(1.f, 1.f, 0.f)), 206),
      expected);
  // A point of the surface (x = r), facing the centre.
  expect_irradiance(estimate_irradiance(lights.set, {0.5f, 0.f, 0.f}, {-1.f, 0.f, 0.f}, 207),
                    expected);
}

TEST(LightIrradianceTest, AllLightsTogetherSumTheirIrradiance) {
  // Square (one-sided), sphere (two-sided, its visible cap) and point light, chosen by power: the
  // estimate divides by the selection probability, so it still converges to the sum of the three
  // irradiances.
  const SceneSpec s;
  const Lights lights{s};
  const Vec3 ref{0.f, 0.f, 2.f}, normal{0.f, 0.f, -1.f};
  const Vec3 to_sphere = s.sphere_center - ref;
  const double d_sphere = length(to_sphere);
  const double cos_sphere = dot_d(normal, to_sphere) / d_sphere;
  ASSERT_LT(std::acos(cos_sphere) + std::asin(s.sphere_radius / d_sphere), kPiD / 2);
  const Vec3 to_point = s.point_position - ref;
  const double d2_point = dot_d(to_point, to_point);
  const double cos_point = dot_d(normal, to_point) / std::sqrt(d2_point);
  ASSERT_GT(cos_point, 0.0);
  std::array<double, 3> expected{};
  for (int c = 0; c < 3; ++c) {
    expected[c] = square_axis_irradiance(s.square_emission[c], s.square_half, 2.0) +
                  sphere_irradiance(s.sphere_emission[c], s.sphere_radius, d_sphere, cos_sphere) +
                  s.point_intensity[c] * cos_point / d2_point;
  }
  expect_irradiance(estimate_irradiance(lights.set, ref, normal, 205), expected);
}

// ----------------------------------------------------------------------------------------------
// Sides, and point lights

TEST(LightSetTest, OneSidedEmittersAreDarkBehind) {
  const Lights square{square_only(false)};
  Pcg32 rng(301, 1);
  for (int k = 0; k < 10000; ++k) {
    LightSample out;
    const bool ok = draw(square.set, {0.3f, -0.2f, -1.f}, rng, out);
    EXPECT_TRUE(!ok || is_black(out.radiance));
  }
  // Inside a one-sided sphere every point faces away.
  const Lights sphere{sphere_only(false)};
  for (int k = 0; k < 10000; ++k) {
    LightSample out;
    const bool ok = draw(sphere.set, {0.1f, 0.f, 0.2f}, rng, out);
    EXPECT_TRUE(!ok || is_black(out.radiance));
  }
  const Material one = emitter("one", Vec3(1.f, 2.f, 3.f), false);
  const Material two = emitter("two", Vec3(1.f, 2.f, 3.f), true);
  const Vec3 n(0.f, 0.f, 1.f);
  EXPECT_EQ(emitted_radiance(one, n, {0.f, 0.6f, 0.8f}), one.emission);
  EXPECT_TRUE(is_black(emitted_radiance(one, n, {0.f, 0.6f, -0.8f})));
  EXPECT_EQ(emitted_radiance(two, n, {0.f, 0.6f, 0.8f}), two.emission);
  EXPECT_EQ(emitted_radiance(two, n, {0.f, 0.6f, -0.8f}), two.emission);
  Material grey;
  EXPECT_TRUE(is_black(emitted_radiance(grey, n, {0.f, 0.f, 1.f})));
}

TEST(LightSetTest, TwoSidedEmittersShineOnBothSides) {
  const Lights square{square_only(true)};
  Pcg32 rng(302, 1);
  for (const float z : {1.f, -1.f}) {
    for (int k = 0; k < 10000; ++k) {
      LightSample out;
      ASSERT_TRUE(draw(square.set, {0.3f, -0.2f, z}, rng, out));
      ASSERT_EQ(out.radiance, square.setup.square_emission);
      // The shadow ray ends on the receiver's side of the light.
      ASSERT_GT(out.target.z * z, 0.f);
    }
  }
}

TEST(LightSetTest, PointLightGivesIntensityOverDistanceSquared) {
  SceneSpec s;
  s.with_square = s.with_sphere = false;
  s.point_position = {1.f, 2.f, 3.f};
  s.point_intensity = {4.f, 8.f, 2.f};
  const Lights lights{s};
  ASSERT_EQ(lights.set.size(), 1u);
  const Vec3 ref{-1.f, 0.5f, 0.f};
  const Vec3 d = s.point_position - ref;
  const float dist2 = dot(d, d);  // 4 + 2.25 + 9
  Pcg32 rng(303, 1);
  for (int k = 0; k < 100; ++k) {
    LightSample out;
    ASSERT_TRUE(draw(lights.set, ref, rng, out));
    EXPECT_TRUE(out.delta);
    EXPECT_EQ(out.pdf, 1.f);  // the only light: chosen with probability 1
    EXPECT_EQ(out.target, s.point_position);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(out.radiance[c], s.point_intensity[c] / 15.25f, 1e-6f);
      EXPECT_NEAR(out.wi[c], d[c] / std::sqrt(dist2), 1e-6f);
    }
  }
}

TEST(LightSetTest, OnlyAChoiceOrAnExtentReadsTheNumbers) {
  // One point light: sample() gives the same sample whatever its numbers, so the path sampler
  // may leave them out (PathSampler::light_bits).
  SceneSpec point_only;
  point_only.with_square = point_only.with_sphere = false;
  const Lights one{point_only};
  ASSERT_EQ(one.set.size(), 1u);
  EXPECT_FALSE(one.set.reads_numbers());
  const Vec3 ref{-1.f, 0.5f, 0.f};
  LightSample zero;
  ASSERT_TRUE(one.set.sample(ref, Vec3(0.f), SelectionNumber::from_float(0.f), 0.f, 0.f, zero));
  Pcg32 rng(11, 2);
  for (int k = 0; k < 50; ++k) {
    LightSample out;
    ASSERT_TRUE(draw(one.set, ref, rng, out));
    EXPECT_EQ(out.wi, zero.wi);
    EXPECT_EQ(out.target, zero.target);
    EXPECT_EQ(out.radiance, zero.radiance);
    EXPECT_EQ(out.pdf, zero.pdf);
  }
  // A lone spot or directional light reads none either.
  for (int kind = 0; kind < 2; ++kind) {
    SceneSpec none;
    none.with_square = none.with_sphere = none.with_point = false;
    Scene scene = build_scene(none);
    if (kind == 0) {
      scene.spot_lights.push_back(
          {Vec3(0.f, 0.f, 4.f), Vec3(0.f, 0.f, -1.f), Vec3(5.f), 40.f, 30.f});
    } else {
      scene.directional_lights.push_back({Vec3(0.f, 0.f, -1.f), Vec3(2.f)});
    }
    SceneData data(scene);
    const LightSet set(data, LightChoice::kPower);
    // A spot light is chosen (the only one); a sun is sampled at every vertex, never chosen.
    ASSERT_EQ(set.size(), kind == 0 ? 1u : 0u);
    ASSERT_EQ(set.always_sampled().size(), kind == 0 ? 0u : 1u);
    EXPECT_FALSE(set.reads_numbers()) << (kind == 0 ? "spot" : "directional");
    if (kind == 1) continue;
    const Vec3 at{0.2f, -0.1f, 0.f};
    LightSample first, other;
    ASSERT_TRUE(set.sample(at, Vec3(0.f), SelectionNumber::from_float(0.f), 0.f, 0.f, first));
    ASSERT_TRUE(set.sample(at, Vec3(0.f), SelectionNumber::from_float(0.7f), 0.3f, 0.9f, other));
    EXPECT_EQ(first.wi, other.wi);
    EXPECT_EQ(first.radiance, other.radiance);
    EXPECT_EQ(first.pdf, other.pdf);
  }
  // Chosen through a tree, even one point light counts as read (the tree reads the choice).
  SceneData tree_data(build_scene(point_only));
  const LightSet tree_set(tree_data, LightChoice::kTree);
  ASSERT_TRUE(tree_set.selection().uses_tree());
  EXPECT_TRUE(tree_set.reads_numbers());
  // A second point light needs the choice; a sphere alone, the point on it.
  Scene two_points = build_scene(point_only);
  two_points.point_lights.push_back({Vec3(0.f, 3.f, 1.f), Vec3(1.f)});
  SceneData two_data(two_points);
  EXPECT_TRUE(LightSet(two_data, LightChoice::kPower).reads_numbers());
  SceneSpec sphere_only;
  sphere_only.with_square = sphere_only.with_point = false;
  EXPECT_TRUE(Lights{sphere_only}.set.reads_numbers());
  EXPECT_TRUE(Lights{SceneSpec{}}.set.reads_numbers());
}

}  // namespace
}  // namespace rayfarm
