// Pixel reconstruction filters (renderer/pixel_filter.h): each filter's samples, weighed, give
// exactly the image through the normalised filter (a deterministic quadrature over the sample
// number), cut and renormalised at the image's edge when sample_border is off; a rendered edge
// equals the edge's coverage convolved with the filter within the computed noise; and a filter
// changes nothing about tiles, passes and threads.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "mc_stats.h"
#include "renderer/pixel_filter.h"
#include "renderer/renderer.h"

namespace rayfarm {
namespace {

constexpr double kPiD = 3.14159265358979323846;

// ---- the filters, written out again from their definitions (Mitsuba 3's rfilters; Cycles'
// Blackman-Harris), so that the sampler is checked against formulas it does not share -------

struct Case {
  std::string name;
  PixelFilter filter;
  std::function<double(double)> f;  // the filter's value at an offset, 0 beyond its radius
};

std::vector<Case> cases() {
  std::vector<Case> out;
  auto add = [&](std::string name, FilterType type, float radius, std::function<double(double)> f) {
    PixelFilter p;
    p.type = type;
    p.radius = radius;
    out.push_back({std::move(name), p, std::move(f)});
  };
  add("box_1.5", FilterType::kBox, 1.5f, [](double x) { return std::fabs(x) <= 1.5 ? 1.0 : 0.0; });
  add("tent", FilterType::kTent, 1.f, [](double x) { return std::max(0.0, 1.0 - std::fabs(x)); });
  add("gaussian", FilterType::kGaussian, 2.f, [](double x) {
    return std::fabs(x) > 2.0 ? 0.0 : std::max(0.0, std::exp(-2.0 * x * x) - std::exp(-8.0));
  });
  add("mitchell", FilterType::kMitchell, 2.f, [](double x) {
    // B = C = 1/3: (7|x|^3 - 12|x|^2 + 16/3) / 6 within 1, (-7/3|x|^3 + 12|x|^2 - 20|x| + 32/3) / 6
    // within 2.
    x = std::fabs(x);
    if (x < 1) return (7 * x * x * x - 12 * x * x + 16.0 / 3) / 6;
    if (x < 2) return (-7.0 / 3 * x * x * x + 12 * x * x - 20 * x + 32.0 / 3) / 6;
    return 0.0;
  });
  add("lanczos2", FilterType::kLanczos, 2.f, [](double x) {
    if (std::fabs(x) > 2) return 0.0;
    if (x == 0) return 1.0;
    return std::sin(kPiD * x) / (kPiD * x) * std::sin(kPiD * x / 2) / (kPiD * x / 2);
  });
  add("blackman_harris", FilterType::kBlackmanHarris, 0.75f, [](double x) {
    if (std::fabs(x) > 0.75) return 0.0;
    const double v = 2 * kPiD * (x / 1.5 + 0.5);
    return 0.35875 - 0.48829 * std::cos(v) + 0.14128 * std::cos(2 * v) - 0.01168 * std::cos(3 * v);
  });
  // Mitsuba's Gaussian as its scalar variants tabulate it: 31 steps over [0, 2], each the value
  // at its inner end.
  out.push_back(out[2]);
  out.back().name = "gaussian_31_steps";
  out.back().filter.steps = 31;
  out.back().f = [g = out[2].f](double x) {
    const double step = std::floor(std::fabs(x) * 31 / 2);
    return step >= 31 ? 0.0 : g(2 * step / 31);
  };
  out.push_back(out[3]);  // Catmull-Rom: Mitchell with B 0, C 1/2
  out.back().name = "catmull_rom";
  out.back().filter.b = 0.f;
  out.back().filter.c = 0.5f;
  out.back().f = [](double x) {
    x = std::fabs(x);
    if (x < 1) return 1.5 * x * x * x - 2.5 * x * x + 1;
    if (x < 2) return -0.5 * x * x * x + 2.5 * x * x - 4 * x + 2;
    return 0.0;
  };
  return out;
}

// Integral of g over [a, b] by the composite Simpson rule on 2^16 intervals, split at zero. For a
// tabulated filter (step > 0, a step function), by the midpoint rule on 2^13 intervals between
// each pair of steps instead, so that no point is evaluated on a jump.
double simpson(const std::function<double(double)>& g, double a, double b, double step = 0.0) {
  if (!(b > a)) return 0.0;
  if (a < 0.0 && b > 0.0) return simpson(g, a, 0.0, step) + simpson(g, 0.0, b, step);
  if (step > 0.0) {
    std::vector<double> cuts{a};
    for (double k = std::floor(a / step) + 1.0; k * step < b; ++k)
      if (k * step > a) cuts.push_back(k * step);
    cuts.push_back(b);
    double total = 0.0;
    constexpr int n = 1 << 13;
    for (size_t p = 0; p + 1 < cuts.size(); ++p) {
      const double lo = cuts[p], w = (cuts[p + 1] - lo) / n;
      for (int i = 0; i < n; ++i) total += g(lo + (i + 0.5) * w) * w;
    }
    return total;
  }
  constexpr int n = 1 << 16;
  const double h = (b - a) / n;
  double s = g(a) + g(b);
  for (int i = 1; i < n; ++i) s += (i % 2 ? 4.0 : 2.0) * g(a + i * h);
  return s * h / 3.0;
}

/// The width of a case's steps (0: not tabulated).
double step_of(const Case& c) {
  return c.filter.steps > 0 ? c.filter.radius / c.filter.steps : 0.0;
}

TEST(PixelFilter, ValuesAreTheFiltersDefinitions) {
  for (const Case& c : cases()) {
    for (double x = -3.0; x <= 3.0; x += 0.0625 / 3)
      // Within the rounding of the parameters, which the filter holds as floats (b = c = 1/3).
      EXPECT_NEAR(filter_value(c.filter, x), c.f(x), 1e-7) << c.name << " at " << x;
  }
  // Mitchell-Netravali cubics integrate to one whatever B and C; Catmull-Rom interpolates.
  EXPECT_NEAR(simpson(cases()[3].f, -2, 2), 1.0, 1e-12);
  EXPECT_NEAR(cases().back().f(0.0), 1.0, 0.0);
  EXPECT_NEAR(cases().back().f(1.0), 0.0, 0.0);
}

// The identity the sampler rests on: over u uniform in [0, 1), the weighted offset has the
// normalised filter's distribution, E[w g(d)] = integral of f g / integral of f over the pixel's
// window. Checked on a midpoint grid of 2^18 sample numbers (a quadrature, not a random test;
// its error is O(1e-6) for the step g), for four functions g, in the middle of the image and at
// its edges with the filter cut there.
TEST(PixelFilter, WeighedSamplesIntegrateTheNormalisedFilter) {
  const std::vector<std::pair<std::string, std::function<double(double)>>> tests = {
      {"1", [](double) { return 1.0; }},
      {"d", [](double d) { return d; }},
      {"d^2", [](double d) { return d * d; }},
      {"step", [](double d) { return d > 0.3 ? 1.0 : 0.0; }},
  };
  constexpr int kGrid = 1 << 18;
  for (const Case& c : cases()) {
    for (bool border : {true, false}) {
      PixelFilter filter = c.filter;
      filter.sample_border = border;
      // A 5-pixel-wide film (pixels 0, 1 cut by a radius of 2 when the border is not sampled)
      // and a 1-pixel-tall one (cut on both sides).
      const FilmSize film{5, 1};
      const FilterSampler sampler(filter, film);
      ASSERT_FALSE(sampler.pixel_box());
      const double r = c.filter.radius;
      struct Pixel {
        bool column;
        uint32_t index, length;
      };
      for (const Pixel& px : {Pixel{true, 2, 5}, Pixel{true, 0, 5}, Pixel{true, 1, 5},
                              Pixel{true, 4, 5}, Pixel{false, 0, 1}}) {
        const double centre = px.index + 0.5;
        const double a = border ? -r : std::max(-r, -centre);
        const double b = border ? r : std::min(r, px.length - centre);
        const double norm = simpson(c.f, a, b, step_of(c));
        std::vector<double> sums(tests.size(), 0.0);
        for (int k = 0; k < kGrid; ++k) {
          const float u = static_cast<float>((k + 0.5) / kGrid);
          const FilterSampler::Offset o =
              px.column ? sampler.sample_x(px.index, u) : sampler.sample_y(px.index, u);
          const double d = double(o.position) - centre;
          ASSERT_GE(d, a - 1e-5) << c.name;
          ASSERT_LE(d, b + 1e-5) << c.name;
          for (size_t t = 0; t < tests.size(); ++t) sums[t] += o.weight * tests[t].second(d);
        }
        for (size_t t = 0; t < tests.size(); ++t) {
          const auto& g = tests[t].second;
          const double expected =
              simpson([&](double x) { return c.f(x) * g(x); }, a, b, step_of(c)) / norm;
          EXPECT_NEAR(sums[t] / kGrid, expected, 2e-5)
              << c.name << (border ? " (border sampled)" : " (cut at the edge)") << ", pixel "
              << px.index << " of " << px.length << ", g = " << tests[t].first;
        }
      }
    }
  }
}

// A tabulated filter's steps fall on the table's bin edges: a positive one's samples all weigh 1
// (no variance from the weights), in whole windows and in windows cut at the image's edge.
TEST(PixelFilter, ATabulatedFiltersSamplesWeighOne) {
  PixelFilter f;
  f.type = FilterType::kGaussian;
  f.radius = 2.f;
  f.steps = 31;
  for (bool border : {true, false}) {
    f.sample_border = border;
    const FilterSampler sampler(f, FilmSize{3, 7});
    for (uint32_t i = 0; i < 3; ++i) {
      for (int k = 0; k < 4096; ++k) {
        const float u = static_cast<float>((k + 0.5) / 4096);
        EXPECT_NEAR(sampler.sample_x(i, u).weight, 1.f, 1e-5f) << "column " << i << ", u " << u;
      }
    }
  }
}

// A description the readers would refuse (a radius of 0 or NaN) is held within the readers'
// range rather than dividing by zero: finite samples with finite weights.
TEST(PixelFilter, AnOutOfRangeRadiusIsHeldInRange) {
  for (const float radius : {0.f, std::nanf(""), 1e30f}) {
    PixelFilter f;
    f.type = FilterType::kTent;
    f.radius = radius;
    f.sample_border = false;
    const FilterSampler sampler(f, FilmSize{2, 2});
    for (const float u : {0.f, 0.3f, 0.99999994f}) {
      const FilterSampler::Offset o = sampler.sample_x(1, u);
      EXPECT_TRUE(std::isfinite(o.position) && std::isfinite(o.weight)) << radius;
      EXPECT_GE(o.position, 0.f);
      EXPECT_LE(o.position, 2.f);
    }
  }
}

TEST(PixelFilter, ThePixelBoxIsNotTabulated) {
  const FilterSampler box(PixelFilter{}, FilmSize{4, 4});
  EXPECT_TRUE(box.pixel_box());
  PixelFilter wide;
  wide.radius = 1.f;
  EXPECT_FALSE(FilterSampler(wide, FilmSize{4, 4}).pixel_box());
}

// ---- a rendered edge ------------------------------------------------------------------------
// An orthographic camera sees a white background with a black half-plane x < e (scene units),
// e 1.3 pixels from the film's left edge. A pixel's expected value is the filter's (normalised)
// weight on the white side: with every sample independent, its standard error comes from the
// render's own second moments. The y axis integrates out (its weights have mean 1).

constexpr uint32_t kWidth = 12, kHeight = 3;
constexpr double kPixel = 0.25;  // scene units per pixel
constexpr double kEdgePixels = 1.3;

Scene edge_scene(const PixelFilter& filter) {
  Scene s;
  s.film = {kWidth, kHeight};
  s.filter = filter;
  s.camera.projection = Camera::Projection::kOrthographic;
  s.camera.view_height = static_cast<float>(kHeight * kPixel);
  s.camera.eye = {0.f, 0.f, 5.f};
  s.camera.look_at = {0.f, 0.f, 0.f};
  s.background = Vec3(1.f);
  s.render.max_depth = 0;
  s.render.sampler = SamplerType::kIndependent;
  Material black;
  black.kind = DiffuseMaterial{Vec3(0.f)};
  s.materials.push_back(black);
  const float e = static_cast<float>(-0.5 * kWidth * kPixel + kEdgePixels * kPixel);
  TriangleMesh quad;
  quad.positions = {{-100, -100, 0}, {e, -100, 0}, {e, 100, 0}, {-100, 100, 0}};
  quad.indices = {0, 1, 2, 0, 2, 3};
  quad.materials = {0, 0};
  quad.origin = "half-plane";
  s.meshes.push_back(quad);
  return s;
}

TEST(PixelFilter, AnEdgeRendersAsItsCoverageConvolvedWithTheFilter) {
  constexpr uint32_t kSpp = 8192;
  std::vector<std::pair<Case, bool>> runs;
  for (const Case& c : cases()) {
    if (c.name == "box_1.5" || c.name == "catmull_rom") continue;
    runs.push_back({c, false});
  }
  runs.push_back({cases()[2], true});  // the Gaussian beyond the border
  runs.push_back({cases()[3], true});  // Mitchell beyond the border
  const double z_max = testing::bonferroni_z(runs.size() * kWidth * kHeight);
  for (const auto& [c, border] : runs) {
    PixelFilter filter = c.filter;
    filter.sample_border = border;
    const Scene scene = edge_scene(filter);
    RenderSettings settings = scene.render;
    settings.spp = kSpp;
    const TileResult r = testing::render_all(scene, settings);
    const double radius = c.filter.radius;
    for (uint32_t x = 0; x < kWidth; ++x) {
      const double centre = x + 0.5;
      const double a = border ? -radius : std::max(-radius, -centre);
      const double b = border ? radius : std::min(radius, kWidth - centre);
      // The window's part on the white side, x > kEdgePixels; none: the pixel is wholly black.
      const bool reaches_white = kEdgePixels - centre < b;
      const double white = simpson(c.f, std::max(a, kEdgePixels - centre), b, step_of(c));
      const double expected = white / simpson(c.f, a, b, step_of(c));  // lobes may make it < 0
      for (uint32_t y = 0; y < kHeight; ++y) {
        const size_t i = (size_t{y} * kWidth + x) * 3;
        const double mean = from_fixed(r.sum[i]) / kSpp;
        const double second = from_fixed(r.sum_sq[i]) / kSpp;
        const double se = std::sqrt(std::max(second - mean * mean, 0.0) / (kSpp - 1.0));
        // Pixels wholly black have no variance and must read exactly 0.
        if (!reaches_white) {
          EXPECT_EQ(mean, 0.0) << c.name << " pixel " << x;
          continue;
        }
        EXPECT_LT(std::fabs(mean - expected), z_max * std::max(se, 1e-9))
            << c.name << (border ? " (border sampled)" : " (cut at the edge)") << ", pixel (" << x
            << ", " << y << "): " << mean << " expected " << expected << " se " << se;
      }
    }
  }
}

// A filter leaves the image a function of (seed, pixel, sample) alone: threads, tiles and
// passes change no bit, with every filter and both border rules.
TEST(PixelFilter, TilesPassesAndThreadsChangeNoBit) {
  for (const Case& c : cases()) {
    for (bool border : {true, false}) {
      PixelFilter filter = c.filter;
      filter.sample_border = border;
      const Scene scene = edge_scene(filter);
      RenderSettings settings = scene.render;
      settings.sampler = SamplerType::kSobol;
      settings.spp = 8;
      settings.seed = 7;
      const Renderer renderer(scene, settings);
      const Film whole = testing::render_with(renderer, 1, 64, 8);
      for (const Film& other :
           {testing::render_with(renderer, 2, 5, 3), testing::render_with(renderer, 2, 2, 1)}) {
        EXPECT_TRUE(whole.sum() == other.sum()) << c.name;
        EXPECT_TRUE(whole.sum_sq() == other.sum_sq()) << c.name;
      }
    }
  }
}

}  // namespace
}  // namespace rayfarm
