// Numerical stability of the path tracer on stiff and extreme cases (docs/stability.md): each
// test states its expectation; Monte Carlo tolerances are numbers of standard errors computed
// from the render itself (mc_stats.h), never guessed constants.
#include <gtest/gtest.h>

#include <cmath>
#include <iterator>
#include <limits>
#include <optional>
#include <ostream>
#include <random>
#include <variant>

#include "common/image/film_output.h"
#include "mc_stats.h"
#include "stability_scenes.h"
#include "test_scenes.h"
#include "tests/support/temp_dir.h"
#include "renderer/bsdfs/bsdf.h"
#include "renderer/camera.h"
#include "renderer/renderer.h"
#include "renderer/scene_data.h"

namespace rayfarm {

/// How gtest prints an integrator in test names and failures.
void PrintTo(IntegratorType t, std::ostream* os) { *os << integrator_name(t); }

namespace {

using testing::Estimate;
using testing::image_estimate;

constexpr IntegratorType kAll[] = {IntegratorType::kNaive, IntegratorType::kNee,
                                   IntegratorType::kMis};

// ---- Stiff transport: the furnace ----------------------------------------------------------

/// Le (1 - rho^(D+1)) / (1 - rho): the furnace's exact radiance when paths have at most D
/// scattering vertices (D + 1 emission terms); Le / (1 - rho) as D grows.
double furnace_radiance(double rho, double le, uint32_t max_depth) {
  return le * (1.0 - std::pow(rho, double(max_depth) + 1.0)) / (1.0 - rho);
}

struct FurnaceCase {
  float rho;
  uint32_t size;  // film side: samples = size^2 * spp
  uint32_t spp;
};

/// How gtest prints a case in test names and failures (rather than its bytes).
void PrintTo(const FurnaceCase& c, std::ostream* os) {
  *os << "albedo " << c.rho << ", " << c.size << "x" << c.size << " pixels, " << c.spp << " spp";
}

class StiffFurnace : public ::testing::TestWithParam<std::tuple<FurnaceCase, IntegratorType>> {};

// Albedo 0.9, 0.99, 0.999: the exact radiance is 10, 100, 1000 x Le. Russian roulette keeps
// the estimator unbiased; max_depth is set where rho^D is far below the tolerance, and the
// renderer's own counter must confirm that the cap cut (almost) nothing.
TEST_P(StiffFurnace, ConvergesToLeOverOneMinusAlbedo) {
  const auto [c, integrator] = GetParam();
  const float le = 0.5f;
  const Scene scene = testing::furnace_scene(c.rho, le, c.size);
  RenderSettings settings;
  settings.integrator = integrator;
  settings.spp = c.spp;
  settings.seed = 11;
  // rho^D < 1e-6: the cap's bias is below 1e-6 of the answer.
  settings.max_depth = static_cast<uint32_t>(std::ceil(std::log(1e-6) / std::log(double(c.rho))));
  const Estimate e = image_estimate(scene, settings);
  const double exact = le / (1.0 - double(c.rho));
  const double capped = furnace_radiance(c.rho, le, settings.max_depth);
  ASSERT_LT(exact - capped, 1e-5 * exact);
  // 5 standard errors: a false alarm has probability 6e-7 per case. Float rounding of the
  // per-vertex weights adds 1e-5 relative.
  EXPECT_NEAR(e.mean, exact, 5.0 * e.standard_error + 1e-5 * exact)
      << integrator_name(integrator) << " rho " << c.rho << ": se " << e.standard_error;
  // The test has power: 5 standard errors are at most 20% of the answer (1024 samples at
  // albedo 0.999, where the cap of the scene format alone would cut 36%).
  EXPECT_LT(e.standard_error, 0.04 * exact);
  EXPECT_EQ(e.nonfinite, 0u);
  // The cap cut at most a few paths, and the renderer says so.
  EXPECT_LT(e.stats.truncated_throughput_per_sample(), 1e-3);
}

std::string furnace_name(const ::testing::TestParamInfo<StiffFurnace::ParamType>& info) {
  const FurnaceCase c = std::get<0>(info.param);
  std::string rho = std::to_string(c.rho).substr(0, 5);
  for (char& ch : rho) ch = ch == '.' ? '_' : ch;
  return std::string(integrator_name(std::get<1>(info.param))) + "_rho" + rho;
}

// Samples chosen for a standard error of about 2% of the answer: the number of bounces is
// geometric, so a sample's relative standard deviation is about sqrt(rho) ~ 1 at any albedo,
// while a path costs about 1 / (1 - rho) rays.
INSTANTIATE_TEST_SUITE_P(Albedos, StiffFurnace,
                         ::testing::Combine(::testing::Values(FurnaceCase{0.9f, 32, 4},
                                                              FurnaceCase{0.99f, 32, 2},
                                                              FurnaceCase{0.999f, 16, 4}),
                                            ::testing::ValuesIn(kAll)),
                         furnace_name);

// With the cap inside the range of path lengths the image is Le (1 - rho^(D+1)) / (1 - rho),
// and the renderer counts the paths it cut: in the furnace each survives update roulette with
// probability rho per bounce at unchanged throughput 1, so a fraction rho^D reaches the cap,
// each carrying throughput exactly 1. Independent samples: the count is then binomial.
TEST(MaxDepthCap, CountsTheTruncatedPathsAndTheirThroughputAndWarns) {
  const float rho = 0.9f, le = 1.f;
  const Scene scene = testing::furnace_scene(rho, le, 32);
  for (IntegratorType integrator : {IntegratorType::kNaive, IntegratorType::kNee}) {
    RenderSettings settings;
    settings.roulette = RouletteType::kUpdate;
    settings.sampler = SamplerType::kIndependent;
    settings.integrator = integrator;
    settings.spp = 4;
    settings.max_depth = 8;
    Renderer renderer(scene, settings);
    RenderStats unit;
    const TileResult r = renderer.render({0, 0, 32, 32}, {0, 4}, &unit);
    const double n = 32.0 * 32.0 * 4.0;
    const double p = std::pow(double(rho), settings.max_depth);
    ASSERT_EQ(unit.samples, uint64_t(n));
    // Binomial count: 5 standard errors.
    EXPECT_NEAR(unit.truncated_fraction(), p, 5.0 * std::sqrt(p * (1.0 - p) / n))
        << integrator_name(integrator);
    EXPECT_DOUBLE_EQ(unit.truncated_throughput, double(unit.truncated_paths));
    // Totals add up the units.
    EXPECT_EQ(renderer.stats().truncated_paths, unit.truncated_paths);
    const std::string line = renderer.report_truncation();
    EXPECT_NE(line.find("max_depth 8 stopped " + std::to_string(unit.truncated_paths) + " of 4096"),
              std::string::npos)
        << line;
    EXPECT_NE(line.find("raise max_depth"), std::string::npos) << line;  // a warning
    // And the image is the truncated series, not the full one.
    double sum = 0.0, sum_sq = 0.0;
    for (size_t i = 1; i < r.sum.size(); i += 3) {
      sum += from_fixed(r.sum[i]);
      sum_sq += from_fixed(r.sum_sq[i]);
    }
    const double mean = sum / n, se = std::sqrt((sum_sq / n - mean * mean) / (n - 1.0));
    EXPECT_NEAR(mean, furnace_radiance(rho, le, settings.max_depth), 5.0 * se);
    EXPECT_GT(le / (1.0 - rho) - mean, 10.0 * se) << "the cap's bias is visible";
  }
}

// The scene format caps max_depth at 1024. At albedo 0.999 that cap keeps 0.999^1024 = 36% of
// the paths alive: the renderer must say so (a warning) rather than return 641 for 1000 silently.
TEST(MaxDepthCap, FormatLimitTruncatesAlbedo0999AndSaysSo) {
  const Scene scene = testing::furnace_scene(0.999f, 1.f, 8);
  RenderSettings settings;
  settings.integrator = IntegratorType::kNee;
  settings.spp = 16;
  settings.max_depth = 1024;
  Renderer renderer(scene, settings);
  RenderStats unit;
  (void)renderer.render({0, 0, 8, 8}, {0, 16}, &unit);
  const double n = 8.0 * 8.0 * 16.0, p = std::pow(0.999, 1024.0);
  EXPECT_NEAR(unit.truncated_fraction(), p, 5.0 * std::sqrt(p * (1.0 - p) / n));
  EXPECT_GT(unit.truncated_throughput_per_sample(), kTruncationWarningLevel);
  // No path carries weight when the cap does not bind: a scene where everything escapes.
  Scene open = testing::empty_scene({0, 0, 0}, {0, 0, 1}, 40.f, 4);
  open.background = Vec3(1.f);
  Renderer open_renderer(open, settings);
  RenderStats none;
  (void)open_renderer.render({0, 0, 4, 4}, {0, 4}, &none);
  EXPECT_EQ(none.truncated_paths, 0u);
  EXPECT_EQ(open_renderer.report_truncation().find("raise max_depth"), std::string::npos);
}

// ---- A tiny, very bright light -------------------------------------------------------------

// The same power from a light 1e-6 of the area (side 1e-3 as long) and 1e6 times the radiance:
// no NaN or infinity; NEE and MIS find it (their images agree within noise and their noise is
// far below naive's, which must hit a target of 1e-6 of the ceiling by chance).
TEST(TinyLight, NoNanAndLightSamplingFindsIt) {
  const Scene tiny = testing::room_with_light(5e-4f, 8e6f, 16);
  const uint32_t block = 8;
  const auto nee = testing::render_blocks(tiny, IntegratorType::kNee, 64, 21, block);
  const auto mis = testing::render_blocks(tiny, IntegratorType::kMis, 64, 22, block);
  const auto naive = testing::render_blocks(tiny, IntegratorType::kNaive, 64, 23, block);
  EXPECT_EQ(nee.nonfinite + mis.nonfinite + naive.nonfinite, 0u);
  EXPECT_GT(testing::expect_same_within_noise(nee, mis, "nee vs mis"), 8u);
  double var_nee = 0.0, var_naive = 0.0;
  for (size_t b = 0; b < nee.mean.size(); ++b) {
    EXPECT_GT(nee.mean[b], 0.0) << "block value " << b << " is dark: the light was not found";
    var_nee += nee.variance_of_mean[b];
    var_naive += naive.variance_of_mean[b];
  }
  // Naive must hit a target of 1e-6 of the ceiling by chance: at 64 spp its image is either
  // black (no hit at all) or orders of magnitude noisier than NEE's.
  double sum_nee = 0.0, sum_naive = 0.0;
  for (size_t b = 0; b < nee.mean.size(); ++b) sum_nee += nee.mean[b], sum_naive += naive.mean[b];
  EXPECT_TRUE(var_naive > 100.0 * var_nee || sum_naive < 0.01 * sum_nee)
      << "naive variance " << var_naive << " vs nee " << var_nee << "; means " << sum_naive
      << " vs " << sum_nee;
}

// ---- Dielectrics ---------------------------------------------------------------------------

/// Mean over the image of a glass furnace and the renderer's truncation statistics.
Estimate glass_estimate(const Scene& scene, IntegratorType integrator, uint32_t spp,
                        uint32_t max_depth = 512) {
  RenderSettings settings;
  settings.integrator = integrator;
  settings.spp = spp;
  settings.max_depth = max_depth;
  settings.seed = 5;
  return image_estimate(scene, settings);
}

// A closed, lossless dielectric in a uniform background of radiance 1 neither creates nor
// destroys energy: every pixel is exactly 1. Nested glass (1.5) / water (1.33) / glass shells
// put three interfaces with relative IORs on each path, including total internal reflection at
// the water-glass interface for rays with impact parameter above 0.75.
TEST(GlassFurnace, ClosedDielectricsConserveEnergy) {
  struct Case {
    const char* name;
    std::vector<float> radii, iors;
  };
  const Case cases[] = {
      {"glass", {1.f}, {1.5f}},
      {"glass-water-glass", {1.f, 0.8f, 0.5f}, {1.5f, 1.33f / 1.5f, 1.5f / 1.33f}},
      {"ior 1.0", {1.f}, {1.f}},
      {"ior 1e4", {1.f}, {1e4f}},
      {"ior 1e20", {1.f}, {1e20f}},
      {"ior 1e30", {1.f}, {1e30f}},
  };
  for (const Case& c : cases) {
    for (IntegratorType integrator : kAll) {
      const Estimate e =
          glass_estimate(testing::glass_furnace(c.radii, c.iors), integrator, 128);
      SCOPED_TRACE(std::string(c.name) + ", " + integrator_name(integrator));
      EXPECT_EQ(e.nonfinite, 0u);
      EXPECT_NEAR(e.mean, 1.0, 5.0 * e.standard_error + 1e-5);
      EXPECT_LT(e.standard_error, 0.02);
      EXPECT_LT(e.stats.truncated_throughput_per_sample(), 1e-4);
    }
  }
}

// From inside a glass sphere the outside's radiance L arrives multiplied by n^2 (radiance is
// compressed by (eta_i / eta_t)^2 across each interface): at the centre every ray meets the
// surface head-on, so every sample is n^2 L whichever lobe it takes.
TEST(GlassFurnace, CameraInsideGlassSeesNSquaredTimesTheOutside) {
  Scene scene = testing::glass_furnace({1.f}, {1.5f});
  scene.camera.eye = Vec3(0.f);
  scene.camera.look_at = {0.f, 0.f, 1.f};
  for (IntegratorType integrator : kAll) {
    const Estimate e = glass_estimate(scene, integrator, 16);
    EXPECT_NEAR(e.mean, 2.25, 5.0 * e.standard_error + 1e-5) << integrator_name(integrator);
    EXPECT_EQ(e.nonfinite, 0u);
  }
  // Off-centre, rays beyond the critical angle are trapped by total internal reflection for
  // ever: finite, and the cap's cut is counted (and would be logged).
  scene.camera.eye = {0.7f, 0.f, 0.f};
  scene.camera.look_at = {0.7f, 0.f, 1.f};
  const Estimate trapped = glass_estimate(scene, IntegratorType::kMis, 4, 64);
  EXPECT_EQ(trapped.nonfinite, 0u);
  EXPECT_GT(trapped.stats.truncated_paths, 0u);
  EXPECT_TRUE(std::isfinite(trapped.mean));
}

// Light -> glass -> diffuse -> camera: the shadow rays of NEE and MIS are blocked by the glass,
// so they must find the caustic through BSDF sampling (a specular bounce counts emission in
// full). All three integrators agree, and the floor under the sphere is lit through it.
TEST(Caustic, AllIntegratorsAgreeOnLightThroughGlass) {
  Scene s = testing::empty_scene({0.f, 2.5f, -2.5f}, {0.f, 0.f, 0.f}, 40.f, 32);
  const uint32_t floor = testing::add_material(s, testing::diffuse(Vec3(0.8f)));
  const uint32_t lamp = testing::add_material(s, testing::diffuse(Vec3(0.f), Vec3(10.f)));
  const uint32_t glass = testing::add_material(s, testing::glass(1.5f));
  testing::add_quad(s, {-2, 0, -2}, {0, 0, 4}, {4, 0, 0}, floor);         // faces +y
  testing::add_quad(s, {-0.3f, 2.5f, -0.3f}, {0.6f, 0, 0}, {0, 0, 0.6f}, lamp);  // faces -y
  s.spheres.push_back({{0.f, 0.8f, 0.f}, 0.5f, glass});
  s.render.max_depth = 16;
  const uint32_t block = 8;
  const auto mis = testing::render_blocks(s, IntegratorType::kMis, 128, 31, block);
  const auto nee = testing::render_blocks(s, IntegratorType::kNee, 128, 32, block);
  const auto naive = testing::render_blocks(s, IntegratorType::kNaive, 256, 33, block);
  EXPECT_EQ(mis.nonfinite + nee.nonfinite + naive.nonfinite, 0u);
  EXPECT_GT(testing::expect_same_within_noise(mis, nee, "mis vs nee"), 40u);
  EXPECT_GT(testing::expect_same_within_noise(mis, naive, "mis vs naive"), 40u);
}

// IOR 1 is no interface at all: a room with an IOR-1 sphere renders as the room without it.
TEST(Dielectric, IndexOneSphereIsInvisibleInTheImage) {
  Scene with = testing::small_room_scene(24, 16);
  for (Sphere& sp : with.spheres) {
    if (auto* glass = std::get_if<DielectricMaterial>(&with.materials[sp.material].kind)) {
      glass->ior = 1.f;
    }
  }
  Scene without = with;
  std::erase_if(without.spheres, [&](const Sphere& sp) {
    return std::holds_alternative<DielectricMaterial>(without.materials[sp.material].kind);
  });
  ASSERT_EQ(without.spheres.size() + 1, with.spheres.size());
  const auto a = testing::render_blocks(with, IntegratorType::kMis, 256, 41, 8);
  const auto b = testing::render_blocks(without, IntegratorType::kMis, 256, 42, 8);
  EXPECT_EQ(a.nonfinite + b.nonfinite, 0u);
  EXPECT_GT(testing::expect_same_within_noise(a, b, "ior 1 vs no sphere"), 12u);
}

// Large and tiny IORs: the Fresnel reflectance is the exact one (computed here in long double)
// and every sampled weight and direction is finite, at every angle including grazing and
// head-on, from both sides.
TEST(Dielectric, ExtremeIorsGiveFiniteExactFresnel) {
  for (const float ior : {1e-30f, 1e-20f, 1e-3f, 1.f, 1.5f, 1e3f, 1e10f, 1e19f, 1e20f, 1e30f}) {
    for (const float cos_i : {1.f, 0.9999999f, 0.7f, 0.3f, 1e-3f, 1e-7f}) {
      for (const float eta : {ior, 1.f / ior}) {
        float cos_t = -1.f;
        const float f = fresnel_dielectric(cos_i, eta, cos_t);
        // Reference in long double.
        const long double e = eta, ci = cos_i;
        const long double c2t = 1.0L - (1.0L - ci * ci) / (e * e);
        long double expected = 1.0L;
        if (c2t > 0.0L) {
          const long double ct = std::sqrt(c2t);
          const long double rp = (e * ci - ct) / (e * ci + ct), rs = (ci - e * ct) / (ci + e * ct);
          expected = 0.5L * (rp * rp + rs * rs);
        }
        SCOPED_TRACE("eta " + std::to_string(eta) + ", cos " + std::to_string(cos_i));
        ASSERT_TRUE(std::isfinite(f));
        EXPECT_GE(f, 0.f);
        EXPECT_LE(f, 1.f);
        EXPECT_NEAR(f, double(expected), 1e-5);
        EXPECT_TRUE(std::isfinite(cos_t));
      }
      // Sampling both lobes from both sides.
      Material m = testing::glass(ior);
      const Bsdf bsdf(m);
      const float sin_i = std::sqrt(std::max(0.f, 1.f - cos_i * cos_i));
      for (const float side : {1.f, -1.f}) {
        for (const float u : {0.f, 0.5f, 0.999999f}) {
          BsdfSample bs;
          ASSERT_TRUE(bsdf.sample({sin_i, 0.f, side * cos_i}, u, 0.5f, 0.5f, bs));
          EXPECT_TRUE(is_finite(bs.wi)) << ior << " " << cos_i;
          EXPECT_NEAR(length(bs.wi), 1.f, 1e-5f);
          EXPECT_FALSE(std::isnan(bs.weight.x)) << ior << " " << cos_i;
        }
      }
    }
  }
}

// ---- Extreme geometry: scale and translation ------------------------------------------------

// The Cornell box scaled by 1e-4 and 1e5, and moved 1e5 away from the origin: the same image
// within noise (no self-intersection acne, no light leaks). Ray offsets follow the error bound
// of each hit point, which scales with the coordinates.
TEST(ExtremeScale, CornellBoxImageDoesNotDependOnScaleOrPosition) {
  const uint32_t size = 32, block = 8, spp = 128;
  const auto reference =
      testing::block_stats(testing::render_all(testing::transformed_cornell(1.f, Vec3(0.f), size),
                                               [&] {
                                                 RenderSettings s;
                                                 s.spp = spp;
                                                 s.seed = 100;
                                                 s.sampler = SamplerType::kIndependent;
                                                 return s;
                                               }()),
                           block);
  struct Case {
    const char* name;
    float scale;
    Vec3 offset;
  };
  const Case cases[] = {{"scale 1e-4", 1e-4f, Vec3(0.f)},
                        {"scale 1e5", 1e5f, Vec3(0.f)},
                        {"moved 1e5", 1.f, Vec3(1e5f, -1e5f, 1e5f)}};
  uint64_t seed = 101;
  for (const Case& c : cases) {
    RenderSettings settings;
    settings.spp = spp;
    settings.seed = seed++;
    settings.sampler = SamplerType::kIndependent;  // block_stats() needs independent samples
    RenderStats stats;
    const TileResult r =
        testing::render_all(testing::transformed_cornell(c.scale, c.offset, size), settings, &stats);
    const auto moved = testing::block_stats(r, block);
    EXPECT_EQ(moved.nonfinite, 0u) << c.name;
    EXPECT_GT(testing::expect_same_within_noise(reference, moved, c.name), 40u);
  }
}

// The offset origin of a ray leaving a hit point lies strictly on the side it leaves from, in
// exact arithmetic, whatever the scale and position: checked in double for hit points computed
// as resolve() computes them, on random triangles from 1e-4 to 1e5 and moved up to 1e5.
TEST(ExtremeScale, RayOffsetsClearTheSurfaceAtEveryScale) {
  std::mt19937 random(99);
  std::uniform_real_distribution<float> unit(-1.f, 1.f), bary(0.f, 1.f);
  int checked = 0;
  for (const float scale : {1e-4f, 1e-2f, 1.f, 1e3f, 1e5f}) {
    for (const float shift : {0.f, 1e3f, 1e5f}) {
      for (int t = 0; t < 2000; ++t) {
        const Vec3 o(shift * unit(random), shift * unit(random), shift * unit(random));
        const Vec3 a = o + Vec3(unit(random), unit(random), unit(random)) * scale;
        const Vec3 b = o + Vec3(unit(random), unit(random), unit(random)) * scale;
        const Vec3 c = o + Vec3(unit(random), unit(random), unit(random)) * scale;
        const Vec3 e1 = b - a, e2 = c - a, ng = cross(e1, e2);
        if (!(length(ng) > 1e-3f * scale * scale)) continue;  // skip slivers
        const Vec3 n = normalize(ng);
        float u = bary(random), v = bary(random);
        if (u + v > 1.f) u = 1.f - u, v = 1.f - v;
        const Vec3 p = a + e1 * u + e2 * v;
        const float err = triangle_point_error(a, b, c);
        // Signed distance to the exact plane through a, b, c, in double.
        const auto side = [&](const Vec3& q) {
          const double ex = double(b.x) - a.x, ey = double(b.y) - a.y, ez = double(b.z) - a.z;
          const double fx = double(c.x) - a.x, fy = double(c.y) - a.y, fz = double(c.z) - a.z;
          const double nx = ey * fz - ez * fy, ny = ez * fx - ex * fz, nz = ex * fy - ey * fx;
          return (double(q.x) - a.x) * nx + (double(q.y) - a.y) * ny + (double(q.z) - a.z) * nz;
        };
        ASSERT_GT(side(offset_ray_origin(p, err, n)), 0.0) << scale << " " << shift;
        ASSERT_LT(side(offset_ray_origin(p, err, -n)), 0.0) << scale << " " << shift;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 20000);
}

// ---- Degenerate and malformed geometry -----------------------------------------------------

/// Renders `scene` with every integrator; expects no dropped sample and finite sums.
void expect_renders_finite(const Scene& scene, uint32_t spp, const std::string& what) {
  for (IntegratorType integrator : kAll) {
    RenderSettings settings = scene.render;
    settings.integrator = integrator;
    settings.spp = spp;
    const TileResult r = testing::render_all(scene, settings);
    EXPECT_TRUE(testing::all_finite(r)) << what << ", " << integrator_name(integrator)
                                        << ": dropped " << r.nonfinite;
  }
}

// Zero-area triangles (collinear, coincident, all at one point), including emissive ones, that
// reached the renderer without the parser (which drops them with a warning): counted, never hit
// as lights, and no NaN.
TEST(DegenerateGeometry, ZeroAreaTrianglesRenderFinite) {
  Scene s = testing::room_with_light(0.5f, 8.f, 8);
  const uint32_t lamp = testing::add_material(s, testing::diffuse(Vec3(0.f), Vec3(100.f), true));
  const uint32_t wall = 0;
  TriangleMesh bad;
  bad.positions = {{0, 0, 0}, {0.5f, 0, 0}, {1, 0, 0}, {0, 0.3f, 0.2f}, {0, 0.3f, 0.2f},
                   {0.2f, -0.2f, 0.5f}};
  // Collinear (0, 1, 2), two equal corners (3, 4, 5), one point (5, 5, 5), tiny sliver.
  bad.indices = {0, 1, 2, 3, 4, 5, 5, 5, 5, 0, 1, 2};
  bad.materials = {lamp, wall, lamp, wall};
  bad.origin = "degenerate";
  s.meshes.push_back(bad);
  const SceneData data(s);
  EXPECT_EQ(data.degenerate_triangles(), 4u);
  expect_renders_finite(s, 16, "zero-area triangles");
}

// Rays that graze a surface: the camera lies in the plane of a quad and looks along it, and a
// second quad is seen at 1e-6 degrees of incidence.
TEST(DegenerateGeometry, GrazingRaysRenderFinite) {
  Scene s = testing::empty_scene({0.f, 0.f, -2.f}, {0.f, 0.f, 0.f}, 10.f, 16);
  s.background = Vec3(1.f);
  const uint32_t white = testing::add_material(s, testing::diffuse(Vec3(0.8f)));
  const uint32_t glass = testing::add_material(s, testing::glass(1.5f));
  const uint32_t lamp = testing::add_material(s, testing::diffuse(Vec3(0.f), Vec3(5.f), true));
  testing::add_quad(s, {-1, 0, -1}, {0, 0, 2}, {2, 0, 0}, white);           // y = 0: the eye's plane
  testing::add_quad(s, {-1, -0.5f, -1}, {2, 0, 0}, {0, 1e-6f, 2}, glass);   // seen almost edge-on
  testing::add_quad(s, {-1, 0.1f, -1}, {0, 1e-7f, 2}, {2, 0, 0}, lamp);      // almost the eye's plane
  s.point_lights.push_back({{0.f, 1e-7f, 0.f}, Vec3(1.f)});                 // on the floor
  s.render.max_depth = 8;
  expect_renders_finite(s, 16, "grazing");
}

// Camera inside closed objects: a diffuse sphere (it sees its inner side, lit by nothing: black),
// a one-sided emissive sphere (it sees the back: black), a glass sphere (finite).
TEST(DegenerateGeometry, CameraInsideClosedObjects) {
  for (const int kind : {0, 1, 2}) {
    Scene s = testing::empty_scene({0.f, 0.f, 0.f}, {0.f, 0.f, 1.f}, 60.f, 8);
    s.background = Vec3(1.f);
    Material m = kind == 2 ? testing::glass(1.5f) : testing::diffuse(Vec3(0.5f));
    if (kind == 1) m.emission = Vec3(3.f);  // one-sided: emits outwards only
    s.spheres.push_back({{0.1f, 0.f, 0.f}, 1.f, testing::add_material(s, m)});
    s.render.max_depth = 64;
    for (IntegratorType integrator : kAll) {
      RenderSettings settings = s.render;
      settings.integrator = integrator;
      settings.spp = 8;
      const TileResult r = testing::render_all(s, settings);
      EXPECT_TRUE(testing::all_finite(r)) << kind;
      if (kind < 2) {
        Fixed total = 0;
        for (Fixed v : r.sum) total += v;
        EXPECT_EQ(total, 0) << "kind " << kind << ", " << integrator_name(integrator);
      }
    }
  }
}

// A one-sided light that faces away from everything lights nothing: every integrator gives an
// exactly black image (light sampling must not count its back, BSDF rays see it black).
TEST(DegenerateGeometry, LightFacingAwayLightsNothing) {
  // The camera is below the light's plane: it sees the floor and the light's dark back.
  Scene s = testing::empty_scene({0.f, 0.8f, -3.f}, {0.f, 0.5f, 0.f}, 50.f, 16);
  const uint32_t white = testing::add_material(s, testing::diffuse(Vec3(0.8f)));
  const uint32_t lamp = testing::add_material(s, testing::diffuse(Vec3(0.f), Vec3(50.f)));
  testing::add_quad(s, {-2, 0, -2}, {0, 0, 4}, {4, 0, 0}, white);            // floor, faces +y
  testing::add_quad(s, {-0.5f, 1.f, -0.5f}, {0, 0, 1}, {1, 0, 0}, lamp);    // faces +y: away
  s.render.max_depth = 8;
  for (IntegratorType integrator : kAll) {
    RenderSettings settings = s.render;
    settings.integrator = integrator;
    settings.spp = 16;
    const TileResult r = testing::render_all(s, settings);
    Fixed total = 0;
    for (Fixed v : r.sum) total += v;
    EXPECT_EQ(total, 0) << integrator_name(integrator);
    EXPECT_EQ(r.nonfinite, 0u);
  }
}

// Coincident surfaces: the room's walls duplicated in place (same material) render as the
// room, within noise: leaving one copy never hits the other (the offset clears both).
TEST(DegenerateGeometry, CoincidentSurfacesRenderAsOne) {
  const Scene single = testing::room_with_light(0.5f, 8.f, 16);
  Scene doubled = single;
  for (size_t m = 0; m + 1 < single.meshes.size(); ++m) doubled.meshes.push_back(single.meshes[m]);
  // The same walls again with the opposite winding.
  for (size_t m = 0; m + 1 < single.meshes.size(); ++m) {
    TriangleMesh flipped = single.meshes[m];
    for (size_t t = 0; t < flipped.triangle_count(); ++t) {
      std::swap(flipped.indices[3 * t + 1], flipped.indices[3 * t + 2]);
    }
    doubled.meshes.push_back(flipped);
  }
  const auto a = testing::render_blocks(single, IntegratorType::kMis, 256, 51, 8);
  const auto b = testing::render_blocks(doubled, IntegratorType::kMis, 256, 52, 8);
  EXPECT_EQ(a.nonfinite + b.nonfinite, 0u);
  EXPECT_GT(testing::expect_same_within_noise(a, b, "coincident walls"), 8u);
}

// Cameras the parser accepts at the edges of its ranges: an up vector of length 1e-30 or 1e17,
// look_at 1e-30 from the eye, a lens of radius 1e17 focused at 1e17. Every ray is finite and of
// unit length (in float, the squared lengths underflowed or overflowed: NaN rays).
TEST(DegenerateGeometry, ExtremeCamerasGiveFiniteUnitRays) {
  struct Case {
    Vec3 eye, look_at, up;
    float aperture, focus;
  };
  const Case cases[] = {
      {{0, 0, 0}, {0, 0, 1}, {0, 1e-30f, 0}, 0.f, 0.f},
      {{0, 0, 0}, {0, 0, 1}, {1e17f, 1e17f, 0}, 0.f, 0.f},
      {{0, 0, 0}, {0, 0, 1e-30f}, {0, 1, 0}, 0.f, 0.f},
      {{1e17f, 1e17f, 1e17f}, {-1e17f, -1e17f, -1e17f}, {0, 1, 0}, 1e17f, 1e17f},
      {{0, 0, 0}, {1e-20f, 0, 0}, {0, 1e-20f, 1e-20f}, 1e-20f, 1e-20f},
  };
  for (const Case& c : cases) {
    Camera cam;
    cam.eye = c.eye;
    cam.look_at = c.look_at;
    cam.up = c.up;
    cam.fov_y_deg = 179.f;
    cam.aperture_radius = c.aperture;
    cam.focus_distance = c.focus;
    const CameraModel model(cam, {7, 5});
    for (float u : {0.f, 0.5f, 0.999f}) {
      const Ray r = model.generate(7.f * u, 5.f * (1.f - u), u, 1.f - u);
      EXPECT_TRUE(is_finite(r.org) && is_finite(r.dir)) << c.up.y << " " << c.look_at.z;
      EXPECT_NEAR(length(r.dir), 1.f, 1e-5f);
    }
  }
}

// A Phong lobe of exponent 1e30 (the format allows it): a perfect mirror in the limit, and
// finite weights on the way (pow underflows to 0, (n + 2) / 2 pi is 1.6e29).
TEST(DegenerateGeometry, PhongExponent1e30RendersFinite) {
  Scene s = testing::room_with_light(0.5f, 8.f, 8);
  Material phong;
  phong.kind = PhongMaterial{Vec3(0.3f), Vec3(0.6f), 1e30f};
  s.materials[0] = phong;
  s.render.max_depth = 6;
  expect_renders_finite(s, 8, "phong 1e30");
}

// ---- Non-finite samples --------------------------------------------------------------------

// A point light of 1e30 W/sr lying 1e-6 above a floor: its irradiance there is 1e42, beyond
// float. Those samples are infinite or out of range: they are dropped and counted, the sums
// stay finite, and the EXR carries no NaN and records the count.
TEST(NonFiniteSamples, AreDroppedCountedAndNeverReachTheImage) {
  Scene s = testing::empty_scene({0.f, 1e-3f, -1e-3f}, {0.f, 0.f, 0.f}, 10.f, 8);
  const uint32_t white = testing::add_material(s, testing::diffuse(Vec3(0.8f)));
  testing::add_quad(s, {-1, 0, -1}, {0, 0, 2}, {2, 0, 0}, white);
  s.point_lights.push_back({{0.f, 1e-6f, 0.f}, Vec3(1e30f)});
  s.render.max_depth = 2;
  RenderSettings settings = s.render;
  settings.integrator = IntegratorType::kNee;
  settings.spp = 8;
  Renderer renderer(s, settings);
  Film film(8, 8);
  film.add(renderer.render({0, 0, 8, 8}, {0, 8}));
  EXPECT_GT(film.nonfinite(), 0u);
  for (float v : film.mean_rgb()) ASSERT_TRUE(std::isfinite(v));
  testing::TempDir dir;
  const auto exr = dir.path() / "dropped.exr";
  write_film(exr, film, {});
  const Image back = read_exr(exr);
  for (float v : back.rgb) ASSERT_TRUE(std::isfinite(v));
  EXPECT_EQ(back.attributes.at("rayfarm:nonfinite"), std::to_string(film.nonfinite()));
  // Control: the same scene with a sane light drops nothing.
  s.point_lights[0].intensity = Vec3(1.f);
  s.point_lights[0].position = {0.f, 0.5f, 0.f};
  Renderer sane(s, settings);
  EXPECT_EQ(sane.render({0, 0, 8, 8}, {0, 8}).nonfinite, 0u);
}

// A sky and a ground of 1.2e17 x 1.2e17 of radiance up to 1e6: their powers (luminance x
// area x pi) overflow float. The light table must stay a probability distribution and the light
// densities finite; otherwise light sampling silently loses them (NaN selection probabilities
// and MIS weights) and NEE and MIS render them black. MIS agrees with naive within noise. NEE
// samples them (nothing is black) but cannot converge here: a uniform point on an emitter of
// 1e34 area almost never falls near the sphere, where the light comes from, and NEE gives BSDF
// hits on emitters no weight. That is the estimator, not the numbers (docs/stability.md).
TEST(NonFiniteSamples, EmittersOfHugePowerAreStillSampled) {
  Scene s = testing::empty_scene({0.f, 1.f, -4.f}, {0.f, 0.f, 0.f}, 40.f, 16);
  const uint32_t white = testing::add_material(s, testing::diffuse(Vec3(0.5f)));
  const uint32_t sky = testing::add_material(s, testing::diffuse(Vec3(0.f), Vec3(1e6f)));
  const uint32_t ground =
      testing::add_material(s, testing::diffuse(Vec3(0.f), Vec3(1e6f, 5e5f, 2e5f)));
  const float h = 6e16f;
  testing::add_quad(s, {-h, 1e3f, -h}, {2 * h, 0, 0}, {0, 0, 2 * h}, sky);     // faces down
  testing::add_quad(s, {-h, -1e3f, -h}, {0, 0, 2 * h}, {2 * h, 0, 0}, ground);  // faces up
  s.spheres.push_back({{0.f, 0.f, 0.f}, 1.f, white});
  s.render.max_depth = 3;
  const auto mis = testing::render_blocks(s, IntegratorType::kMis, 32, 61, 8);
  const auto nee = testing::render_blocks(s, IntegratorType::kNee, 32, 62, 8);
  const auto naive = testing::render_blocks(s, IntegratorType::kNaive, 32, 63, 8);
  EXPECT_EQ(mis.nonfinite + nee.nonfinite + naive.nonfinite, 0u);
  EXPECT_GT(testing::expect_same_within_noise(mis, naive, "mis vs naive"), 8u);
  for (size_t b = 0; b < nee.mean.size(); ++b) EXPECT_GT(nee.mean[b], 0.0) << "block value " << b;
}

// Geometry beyond Embree's range (1.8e18; the parser refuses coordinates above 1e17): built in
// code, such a scene must not abort the process (Debian's Embree asserts on invalid rays). The
// out-of-range quads are ignored by Embree; shadow rays towards them count as blocked, and
// rays with huge directions are rescaled exactly.
TEST(DegenerateGeometry, CoordinatesBeyondEmbreeRangeDoNotAbort) {
  Scene s = testing::empty_scene({0.f, 1.f, -4.f}, {0.f, 0.f, 0.f}, 40.f, 8);
  const uint32_t white = testing::add_material(s, testing::diffuse(Vec3(0.5f)));
  const uint32_t sky = testing::add_material(s, testing::diffuse(Vec3(0.f), Vec3(2.f)));
  const float h = 6e18f;
  testing::add_quad(s, {-h, 1e3f, -h}, {2 * h, 0, 0}, {0, 0, 2 * h}, sky);
  testing::add_quad(s, {-1e3f, 1e18f, -1e3f}, {2e3f, 0, 0}, {0, 0, 2e3f}, sky);  // far but valid
  s.spheres.push_back({{0.f, 0.f, 0.f}, 1.f, white});
  s.point_lights.push_back({{0.f, 1e30f, 0.f}, Vec3(1.f)});
  s.render.max_depth = 3;
  expect_renders_finite(s, 8, "coordinates beyond 1.8e18");
  Scene eye_far = s;  // the camera itself out of range: every ray escapes
  eye_far.camera.eye = {0.f, 0.f, -1e19f};
  expect_renders_finite(eye_far, 2, "camera beyond 1.8e18");
}

// The conversion of rays into Embree's form: the usual ray goes through unchanged; a direction
// beyond 2^60 is divided by a power of two and the hit's t multiplied back; an origin
// beyond Embree's range, a non-finite component or a NaN interval finds nothing and counts as
// blocked.
TEST(DegenerateGeometry, RaysAreCheckedAndRescaledExactly) {
  Scene s = testing::empty_scene({0.f, 0.f, -4.f}, {0.f, 0.f, 0.f}, 40.f, 8);
  const uint32_t white = testing::add_material(s, testing::diffuse(Vec3(0.5f)));
  testing::add_quad(s, {-1.f, -1.f, 10.f}, {2.f, 0.f, 0.f}, {0.f, 2.f, 0.f}, white);
  const SceneData data(s);
  const Bvh& bvh = data.bvh();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();

  const std::optional<RayHit> plain = bvh.intersect(Ray{{0.f, 0.f, 0.f}, {0.f, 0.f, 1.f}});
  ASSERT_TRUE(plain.has_value());
  EXPECT_NEAR(plain->t, 10.f, 1e-5f);
  for (const float scale : {0x1p60f, 0x1p61f, 0x1p100f, 0x1p127f}) {
    const std::optional<RayHit> huge = bvh.intersect(Ray{{0.f, 0.f, 0.f}, {0.f, 0.f, scale}});
    ASSERT_TRUE(huge.has_value()) << scale;
    // The same distance in units of the longer direction: Embree's arithmetic on a direction
    // scaled by a power of two scales by it exactly.
    EXPECT_EQ(huge->t * scale, plain->t) << scale;
    EXPECT_EQ(huge->prim, plain->prim);
    // An open end (tfar infinite) is accepted at any scale.
    EXPECT_TRUE(bvh.intersect(Ray{{0.f, 0.f, 0.f}, {0.f, 0.f, scale}, 0.f, inf}).has_value());
    // A segment reaching past the quad is blocked, one stopping short is not.
    EXPECT_TRUE(bvh.occluded(Ray{{0.f, 0.f, 0.f}, {0.f, 0.f, scale}, 0.f, 11.f / scale}));
    EXPECT_FALSE(bvh.occluded(Ray{{0.f, 0.f, 0.f}, {0.f, 0.f, scale}, 0.f, 9.f / scale}));
  }
  const Ray refused[] = {
      Ray{{0.f, 0.f, -2e18f}, {0.f, 0.f, 1.f}},  // origin beyond Embree's range
      Ray{{nan, 0.f, 0.f}, {0.f, 0.f, 1.f}},
      Ray{{0.f, 0.f, 0.f}, {0.f, 0.f, inf}},
      Ray{{0.f, 0.f, 0.f}, {0.f, nan, 1.f}},
      Ray{{0.f, 0.f, 0.f}, {0.f, 0.f, 1.f}, nan, 20.f},
      Ray{{0.f, 0.f, 0.f}, {0.f, 0.f, 1.f}, 0.f, nan},
      Ray{{0.f, -inf, 0.f}, {0.f, 0.f, 1.f}},
      Ray{{0.f, 0.f, 0.f}, {nan, 0.f, 0x1p100f}},  // a NaN beside a component to rescale
  };
  for (size_t i = 0; i < std::size(refused); ++i) {
    EXPECT_FALSE(bvh.intersect(refused[i]).has_value()) << "ray " << i;
    EXPECT_TRUE(bvh.occluded(refused[i])) << "ray " << i;
  }
}

}  // namespace
}  // namespace rayfarm
