// The light tree (renderer/lights/light_tree.h): its probabilities form a distribution at every
// point and are the ones its choices are made with, bit for bit; merged bounds never rule out
// a point that one of their lights can light; the build stays within its depth limit whatever
// the lights' layout; and rendering through it gives the same expected image as selection by
// power, with less noise where a scene has many lights.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <string>
#include <vector>

#include "common/image/fixed.h"
#include "common/scene/parser.h"
#include "mc_stats.h"
#include "stability_scenes.h"
#include "test_scenes.h"
#include "tests/support/normal_quantile.h"
#include "renderer/lights/light_set.h"
#include "renderer/lights/light_tree.h"
#include "renderer/renderer.h"
#include "renderer/samplers/rng.h"

namespace rayfarm {
namespace {

const std::string kScenes = std::string(RAYFARM_SOURCE_DIR) + "/scenes/";

Vec3 random_unit(Pcg32& rng) {
  const float z = 1.f - 2.f * rng.next_float();
  const float r = std::sqrt(std::max(0.f, 1.f - z * z));
  const float phi = 2.f * kPi * rng.next_float();
  return {r * std::cos(phi), r * std::sin(phi), z};
}

Vec3 random_point(Pcg32& rng, float extent) {
  return {extent * (2.f * rng.next_float() - 1.f), extent * (2.f * rng.next_float() - 1.f),
          extent * (2.f * rng.next_float() - 1.f)};
}

/// Random lights of every kind the tree holds: one- and two-sided triangles, spheres, points
/// and spots, of intensities spread over four decades.
std::vector<LightBounds> random_lights(Pcg32& rng, size_t count, float extent) {
  std::vector<LightBounds> out;
  for (size_t i = 0; i < count; ++i) {
    LightBounds b;
    const Vec3 c = random_point(rng, extent);
    const uint32_t kind = rng.next_u32() % 4;
    if (kind == 0) {  // a triangle
      const Vec3 v1 = c + random_point(rng, 0.2f), v2 = c + random_point(rng, 0.2f);
      b.lo = Vec3(std::min({c.x, v1.x, v2.x}), std::min({c.y, v1.y, v2.y}),
                  std::min({c.z, v1.z, v2.z}));
      b.hi = Vec3(std::max({c.x, v1.x, v2.x}), std::max({c.y, v1.y, v2.y}),
                  std::max({c.z, v1.z, v2.z}));
      b.axis = normalize(cross(v1 - c, v2 - c));
      b.cos_o = 1.f;
      b.cos_e = 0.f;
      b.two_sided = rng.next_u32() % 3 == 0;
    } else if (kind == 1) {  // a sphere
      const float r = 0.01f + 0.2f * rng.next_float();
      b.lo = c - Vec3(r), b.hi = c + Vec3(r);
      b.cos_o = -1.f;
    } else if (kind == 2) {  // a point light
      b.lo = b.hi = c;
      b.cos_o = -1.f;
    } else {  // a spot light
      b.lo = b.hi = c;
      b.axis = random_unit(rng);
      b.cos_o = 1.f;
      b.cos_e = std::cos(0.1f + 1.4f * rng.next_float());
    }
    b.intensity = std::pow(10.0, 4.0 * rng.next_float());
    out.push_back(b);
  }
  return out;
}

std::vector<int32_t> identity(size_t n) {
  std::vector<int32_t> out(n);
  for (size_t i = 0; i < n; ++i) out[i] = static_cast<int32_t>(i);
  return out;
}

/// A receiver normal: the zero vector (light from every side) one time in four.
Vec3 random_normal(Pcg32& rng) { return rng.next_u32() % 4 == 0 ? Vec3(0.f) : random_unit(rng); }

TEST(LightTree, ProbabilitiesSumToOneAndAreTheChoicesOwn) {
  // At a point, the lights' probabilities and the chance that a choice fails (a walk that meets
  // a node whose children both have importance 0: their looser group bounds let it through)
  // add up to 1; where no light can reach the point, every choice fails. Each choice reports
  // exactly the probability that probability() computes for its light (what MIS weights read).
  // The failures of 400 choices per point are held to their binomial spread (5 sigma: with
  // 1000 points, a false alarm below 1e-3).
  Pcg32 rng(11, 1);
  for (const size_t count : {size_t{1}, size_t{2}, size_t{3}, size_t{17}, size_t{300}}) {
    const std::vector<LightBounds> lights = random_lights(rng, count, 5.f);
    const LightTree tree(lights, identity(count));
    EXPECT_EQ(tree.node_count(), 2 * count - 1);
    int complete = 0, zero = 0;
    for (int k = 0; k < 200; ++k) {
      const Vec3 p = random_point(rng, 6.f), n = random_normal(rng);
      double sum = 0.0;
      for (size_t l = 0; l < count; ++l) sum += tree.probability(p, n, static_cast<int32_t>(l));
      // A product of at most depth() float factors per light: a relative error of a few 1e-7
      // per factor.
      EXPECT_LE(sum, 1.0 + 1e-5) << count << " lights, point " << k;
      complete += std::fabs(sum - 1.0) < 1e-5;
      zero += sum == 0.0;
      constexpr int kChoices = 400;
      int failed = 0;
      for (int j = 0; j < kChoices; ++j) {
        int32_t light = -1;
        float probability = 0.f;
        if (!tree.choose(p, n, rng.next_float(), light, probability)) {
          ++failed;
          continue;
        }
        ASSERT_GE(light, 0);
        ASSERT_LT(light, static_cast<int32_t>(count));
        EXPECT_EQ(probability, tree.probability(p, n, light));
        EXPECT_GT(probability, 0.f);
      }
      const double q = std::clamp(1.0 - sum, 0.0, 1.0);
      if (sum == 0.0) {
        EXPECT_EQ(failed, kChoices) << "no light can reach this point";
      }
      EXPECT_LE(std::fabs(failed - q * kChoices), 5.0 * std::sqrt(kChoices * q * (1.0 - q)) + 1.0)
          << count << " lights, point " << k << ": probabilities sum to " << sum;
    }
    // With one or two lights there is no node below the root to fail at.
    if (count <= 2) {
      EXPECT_EQ(complete + zero, 200) << count << " lights";
    }
    EXPECT_EQ(tree.probability(Vec3(0.f), Vec3(0.f), -1), 0.f);
    EXPECT_EQ(tree.probability(Vec3(0.f), Vec3(0.f), static_cast<int32_t>(count)), 0.f);
  }
}

TEST(LightTree, ChoicesFollowTheirProbabilities) {
  // 48 lights seen from one point: 200,000 choices from independent uniforms; each light's
  // count (and the failed choices') against its binomial expectation (normal approximation,
  // rare categories pooled), Bonferroni over the categories at a 1e-3 false alarm.
  Pcg32 rng(12, 1);
  const size_t count = 48;
  const LightTree tree(random_lights(rng, count, 4.f), identity(count));
  const Vec3 p(0.5f, -0.3f, 0.2f), n = normalize(Vec3(0.3f, 1.f, -0.2f));
  constexpr int kDraws = 200000;
  std::vector<int> hits(count + 1, 0);  // the last: failed choices
  for (int k = 0; k < kDraws; ++k) {
    int32_t light = -1;
    float probability = 0.f;
    ++hits[tree.choose(p, n, SelectionNumber{rng.next_u32()}.as_double(), light, probability)
               ? light
               : count];
  }
  std::vector<double> q(count + 1, 1.0);
  for (size_t l = 0; l < count; ++l) {
    q[l] = tree.probability(p, n, static_cast<int32_t>(l));
    q[count] -= q[l];
  }
  q[count] = std::max(q[count], 0.0);
  EXPECT_LT(q[count], 0.5) << "most choices at this point fail";
  // Categories expected fewer than 25 times are pooled into one, so that every count tested is
  // near enough to normal for its z bound.
  std::vector<std::pair<double, int>> tested;  // (probability, count)
  double rare_q = 0.0;
  int rare_hits = 0;
  for (size_t l = 0; l <= count; ++l) {
    if (q[l] < 1e-9) {
      EXPECT_EQ(hits[l], 0) << "light " << l << " has probability " << q[l];
    } else if (q[l] * kDraws < 25.0) {
      rare_q += q[l], rare_hits += hits[l];
    } else {
      tested.emplace_back(q[l], hits[l]);
    }
  }
  // The pooled category is tested only where it is as large as the others.
  if (rare_q * kDraws >= 25.0) tested.emplace_back(rare_q, rare_hits);
  const double z_max = testing::two_sided_z(1e-3 / double(tested.size()));
  for (const auto& [p_cat, n_cat] : tested) {
    const double expected = p_cat * kDraws, sd = std::sqrt(kDraws * p_cat * (1.0 - p_cat));
    EXPECT_LT(std::fabs(n_cat - expected), z_max * sd)
        << n_cat << " choices, expected " << expected;
  }
}

TEST(LightTree, MergedBoundsRuleOutNoPointThatALightCanReach) {
  // Whatever lights are merged, a point that one of them can light (importance > 0) keeps a
  // positive importance for the group: the cone union holds every normal and emission spread.
  Pcg32 rng(13, 1);
  int checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const std::vector<LightBounds> lights = random_lights(rng, 2 + rng.next_u32() % 6, 3.f);
    LightBounds group = lights[0];
    for (size_t i = 1; i < lights.size(); ++i) group = merge(group, lights[i]);
    EXPECT_LE(group.cos_o, 1.f);
    EXPECT_GE(group.cos_o, -1.f);
    EXPECT_NEAR(length(group.axis), 1.f, 1e-5f);
    for (int k = 0; k < 50; ++k) {
      const Vec3 p = random_point(rng, 8.f), n = random_normal(rng);
      bool any = false;
      for (const LightBounds& l : lights) any |= l.importance(p, n) > 0.0;
      if (!any) continue;
      ++checked;
      EXPECT_GT(group.importance(p, n), 0.0) << "trial " << trial << ", point " << k;
    }
  }
  EXPECT_GT(checked, 5000);
}

TEST(LightTree, ImportanceFollowsSidesDistanceAndIntensity) {
  LightBounds tri;  // one-sided, facing +z, around the origin
  tri.lo = Vec3(-0.1f, -0.1f, 0.f), tri.hi = Vec3(0.1f, 0.1f, 0.f);
  tri.axis = Vec3(0.f, 0.f, 1.f);
  tri.intensity = 1.0;
  EXPECT_GT(tri.importance(Vec3(0.f, 0.f, 2.f), Vec3(0.f)), 0.0);
  EXPECT_EQ(tri.importance(Vec3(0.f, 0.f, -2.f), Vec3(0.f)), 0.0);  // behind it
  // A receiver facing away from the light takes nothing from it; facing it, something.
  EXPECT_EQ(tri.importance(Vec3(0.f, 0.f, 2.f), Vec3(0.f, 0.f, 1.f)), 0.0);
  EXPECT_GT(tri.importance(Vec3(0.f, 0.f, 2.f), Vec3(0.f, 0.f, -1.f)), 0.0);
  tri.two_sided = true;
  EXPECT_GT(tri.importance(Vec3(0.f, 0.f, -2.f), Vec3(0.f)), 0.0);
  // Far away: 1 / d^2 and proportional to intensity.
  LightBounds point;
  point.cos_o = -1.f;
  point.intensity = 3.0;
  const double near = point.importance(Vec3(0.f, 10.f, 0.f), Vec3(0.f));
  const double far = point.importance(Vec3(0.f, 20.f, 0.f), Vec3(0.f));
  EXPECT_NEAR(near / far, 4.0, 1e-5);
  EXPECT_NEAR(near, 3.0 / 100.0, 1e-8);
  // A spot lights its cone only.
  LightBounds spot = point;
  spot.axis = Vec3(0.f, 1.f, 0.f);
  spot.cos_o = 1.f;
  spot.cos_e = std::cos(0.3f);
  EXPECT_GT(spot.importance(Vec3(0.f, 5.f, 1.f), Vec3(0.f)), 0.0);   // 0.197 rad off axis
  EXPECT_EQ(spot.importance(Vec3(0.f, 5.f, 2.f), Vec3(0.f)), 0.0);   // 0.381 rad
  EXPECT_EQ(spot.importance(Vec3(0.f, -5.f, 0.f), Vec3(0.f)), 0.0);  // behind
}

TEST(LightTree, DepthStaysBoundedWhateverTheLayout) {
  // Lights spaced geometrically along a line, the layout that drives a cost-based split to peel
  // off one light at a time; and lights all at one point, which no split separates.
  std::vector<LightBounds> line, stacked;
  for (int k = 0; k < 3000; ++k) {
    LightBounds b;
    b.lo = b.hi = Vec3(std::pow(1.01f, float(k)), 0.f, 0.f);
    b.cos_o = -1.f;
    b.intensity = 1.0 + k % 7;
    line.push_back(b);
    b.lo = b.hi = Vec3(1.f, 2.f, 3.f);
    stacked.push_back(b);
  }
  const LightTree a(line, identity(line.size()));
  EXPECT_LE(a.depth(), LightTree::kMaxDepth);
  const LightTree b(stacked, identity(stacked.size()));
  EXPECT_EQ(b.depth(), 12u);  // balanced: ceil(log2 3000)
  for (const LightTree* tree : {&a, &b}) {
    for (const Vec3& p : {Vec3(0.f, 1.f, 0.f), Vec3(50.f, -3.f, 2.f), Vec3(1e5f, 1.f, 1.f)}) {
      double sum = 0.0;
      for (int32_t l = 0; l < 3000; ++l) sum += tree->probability(p, Vec3(0.f), l);
      EXPECT_NEAR(sum, 1.0, 1e-4);
    }
  }
  // Lights at one point: chosen by intensity alone.
  const double total = [&] {
    double t = 0.0;
    for (const LightBounds& l : stacked) t += l.intensity;
    return t;
  }();
  for (const int32_t l : {0, 1, 6, 2999})
    EXPECT_NEAR(b.probability(Vec3(0.f), Vec3(0.f), l), stacked[l].intensity / total, 1e-6);
}

TEST(LightTree, BuildsTheSameTreeEveryTime) {
  Pcg32 rng(14, 1);
  const std::vector<LightBounds> lights = random_lights(rng, 500, 5.f);
  const LightTree a(lights, identity(lights.size())), b(lights, identity(lights.size()));
  ASSERT_EQ(a.node_count(), b.node_count());
  for (int k = 0; k < 2000; ++k) {
    const Vec3 p = random_point(rng, 6.f), n = random_normal(rng);
    const float u = rng.next_float();
    int32_t la = -1, lb = -1;
    float pa = 0.f, pb = 0.f;
    EXPECT_EQ(a.choose(p, n, u, la, pa), b.choose(p, n, u, lb, pb));
    EXPECT_EQ(la, lb);
    EXPECT_EQ(pa, pb);
  }
}

// ---- delta lights: the tree must give them a chance wherever they light ----------------------

/// Orthonormal vector to the unit a.
Vec3 perpendicular(const Vec3& a) {
  const Vec3 t = std::fabs(a.x) < 0.9f ? Vec3(1.f, 0.f, 0.f) : Vec3(0.f, 1.f, 0.f);
  return normalize(cross(a, t));
}

TEST(LightTree, EverySpotAndPointLightKeepsAChanceWhereItLights) {
  // BSDF rays never find a point or spot light: where one lights a point, the tree must give it
  // a probability above 0 there, or its light is lost. Spots clustered together and aimed at one
  // target (nearly parallel axes, whose merged cones must still hold every axis), with cutoffs
  // from 0.05 degrees to 90 (flush downlights), beside point lights; points probed on both sides
  // of each cone's edge, with receiver normals that face the light.
  Pcg32 rng(15, 1);
  Scene scene;
  const Vec3 target(0.f, -4.f, 0.3f);
  const float cutoffs[] = {0.05f, 0.2f, 0.5f, 1.f, 5.f, 30.f, 60.f, 89.9f, 90.f};
  for (int i = 0; i < 27; ++i) {
    SpotLight spot;
    spot.position = Vec3(0.01f * float(i % 5), 2.f + 0.002f * float(i), 0.003f * float(i / 5));
    spot.direction = normalize(target - spot.position);
    spot.intensity = Vec3(1.f + float(i % 4));
    spot.cutoff_deg = cutoffs[i % 9];
    spot.beam_width_deg = spot.cutoff_deg;  // full intensity up to the edge
    scene.spot_lights.push_back(spot);
  }
  for (int i = 0; i < 6; ++i) scene.point_lights.push_back({random_point(rng, 3.f), Vec3(2.f)});
  SceneData data(scene);
  const LightSet lights(data, LightChoice::kTree);
  ASSERT_TRUE(lights.selection().uses_tree());
  const int32_t points = 6, spots = 27;  // the set holds point lights first, then spots
  int lit = 0;
  for (int32_t s = 0; s < spots; ++s) {
    const SpotLight& spot = scene.spot_lights[s];
    const std::optional<DeltaSpotLight> light =
        DeltaSpotLight::make(scene, static_cast<uint32_t>(s));
    ASSERT_TRUE(light);
    const float cutoff = spot.cutoff_deg * kPi / 180.f;
    const Vec3 side = perpendicular(spot.direction), up = cross(spot.direction, side);
    for (int k = 0; k < 3000; ++k) {
      // An angle within 1e-3 (relative) of the cutoff on either side, a random azimuth and
      // distance.
      const float theta = std::min(kPi, cutoff * (1.f + 2e-3f * (rng.next_float() - 0.5f)));
      const float phi = 2.f * kPi * rng.next_float();
      const Vec3 dir = spot.direction * std::cos(theta) +
                       (side * std::cos(phi) + up * std::sin(phi)) * std::sin(theta);
      const Vec3 p = spot.position + dir * (0.5f + 8.f * rng.next_float());
      LightSample out;
      if (!light->sample(p, 1.f, 0.5f, 0.5f, out)) continue;  // not lit by this spot
      ++lit;
      // A receiver that faces the light (any normal with a positive cosine to it).
      Vec3 n = random_unit(rng);
      if (dot(n, out.wi) <= 0.f) n = -n;
      EXPECT_GT(lights.selection_probability(points + s, p, n), 0.f)
          << "spot " << s << " (cutoff " << spot.cutoff_deg << " deg) lights " << p.x << "," << p.y
          << "," << p.z << " but has no chance there";
      EXPECT_GT(lights.selection_probability(points + s, p, Vec3(0.f)), 0.f);
    }
  }
  EXPECT_GT(lit, 20000);
  // Point lights, everywhere, with receivers barely facing them (cosines down to 1e-6).
  for (int k = 0; k < 20000; ++k) {
    const Vec3 p = random_point(rng, 5.f);
    const int32_t l = static_cast<int32_t>(rng.next_u32() % points);
    const Vec3 wi = normalize(scene.point_lights[l].position - p);
    const Vec3 t = perpendicular(wi);
    const float c = std::pow(10.f, -6.f * rng.next_float());
    const Vec3 n = normalize(wi * c + t * std::sqrt(1.f - c * c));
    if (!(dot(n, wi) > 0.f)) continue;
    EXPECT_GT(lights.selection_probability(l, p, n), 0.f) << "point light " << l;
  }
}

TEST(LightSelection, TreeChoicesReportTheirProbabilityBesideLightsAtInfinity) {
  // A tree beside a sky and a sun: each choice's probability (the group's share times the
  // tree's) is exactly what probability() computes, the number MIS weights read.
  Pcg32 rng(16, 1);
  std::vector<LightBounds> placed = random_lights(rng, 40, 4.f);
  std::vector<double> powers;
  std::vector<std::optional<LightBounds>> bounds;
  for (const LightBounds& b : placed) {
    powers.push_back(4.0 * kPi * b.intensity);
    bounds.emplace_back(b);
  }
  double placed_power = 0.0;
  for (const double w : powers) placed_power += w;
  // Lights at infinity with a quarter and a twentieth of that power, one among the others.
  powers.insert(powers.begin() + 10, 0.25 * placed_power);
  bounds.insert(bounds.begin() + 10, std::nullopt);
  powers.push_back(0.05 * placed_power);
  bounds.emplace_back(std::nullopt);
  const LightSelection selection(powers, bounds, LightChoice::kAuto);
  ASSERT_TRUE(selection.uses_tree());
  int infinite = 0;
  for (int k = 0; k < 20000; ++k) {
    const Vec3 p = random_point(rng, 5.f), n = random_normal(rng);
    int32_t light = -1;
    float probability = 0.f;
    if (!selection.choose(p, n, SelectionNumber{rng.next_u32()}, light, probability)) continue;
    ASSERT_GE(light, 0);
    ASSERT_LT(light, static_cast<int32_t>(powers.size()));
    EXPECT_EQ(probability, selection.probability(p, n, light)) << "light " << light;
    if (!bounds[light]) {
      ++infinite;
      EXPECT_EQ(probability, selection.infinite_probability(light));
    }
  }
  EXPECT_GT(infinite, 2000);  // about 23% of 20,000
}

// ---- rendering through the tree ----------------------------------------------------------------

std::vector<float> pixel_means(const Scene& scene, RenderSettings settings, LightChoice choice,
                               uint64_t seed) {
  settings.seed = seed;
  const Renderer renderer(scene, settings, BsdfKinds::kAll, choice);
  const TileResult r =
      renderer.render({0, 0, scene.film.width, scene.film.height}, {0, settings.spp});
  EXPECT_EQ(r.nonfinite, 0u);
  return testing::pixel_means(r, settings.spp);
}

struct RenderCase {
  std::string name;
  Scene scene;
  IntegratorType integrator;
  uint32_t spp = 16;
};

Scene shrunk(const std::string& file, uint32_t w, uint32_t h) {
  Scene s = load_scene(kScenes + file);
  s.film = {w, h};
  return s;
}

/// A closed room lit by five large panels of different colours and sizes on its walls and
/// ceiling, close to the surfaces they light: BSDF rays find the panels often, so MIS weights
/// (the tree's probability of the light a BSDF ray found) shape much of the image.
Scene panel_room(uint32_t w, uint32_t h) {
  using testing::add_material, testing::add_quad, testing::diffuse;
  Scene s;
  s.film = {w, h};
  s.camera.eye = {0.f, 0.f, -0.9f};
  s.camera.look_at = {0.f, -0.2f, 1.f};
  s.camera.fov_y_deg = 80.f;
  const uint32_t wall = add_material(s, diffuse(Vec3(0.6f)));
  const uint32_t green = add_material(s, diffuse(Vec3(0.2f, 0.6f, 0.2f)));
  add_quad(s, {-1, -1, -1}, {0, 0, 2}, {2, 0, 0}, wall);   // floor
  add_quad(s, {-1, 1, -1}, {2, 0, 0}, {0, 0, 2}, wall);    // ceiling
  add_quad(s, {-1, -1, 1}, {2, 0, 0}, {0, 2, 0}, wall);    // back
  add_quad(s, {-1, -1, -1}, {0, 2, 0}, {2, 0, 0}, wall);   // front
  add_quad(s, {-1, -1, -1}, {0, 0, 2}, {0, 2, 0}, green);  // left
  add_quad(s, {1, -1, -1}, {0, 2, 0}, {0, 0, 2}, wall);    // right
  const float in = 0.999f;
  add_quad(s, {-0.6f, in, -0.2f}, {0.5f, 0, 0}, {0, 0, 0.9f},
           add_material(s, diffuse(Vec3(0.f), {4, 3, 2})));
  add_quad(s, {0.3f, in, 0.1f}, {0.4f, 0, 0}, {0, 0, 0.4f},
           add_material(s, diffuse(Vec3(0.f), {1, 2, 6})));
  add_quad(s, {-in, -0.5f, 0.f}, {0, 0, 0.6f}, {0, 0.9f, 0},
           add_material(s, diffuse(Vec3(0.f), {3, 3, 3})));
  add_quad(s, {in, -0.8f, 0.3f}, {0, 0.3f, 0}, {0, 0, 0.3f},
           add_material(s, diffuse(Vec3(0.f), {8, 1, 1})));
  add_quad(s, {-0.2f, -0.9f, in}, {0.8f, 0, 0}, {0, 0.2f, 0},
           add_material(s, diffuse(Vec3(0.f), {2, 5, 2})));
  s.render.max_depth = kUnlimitedDepth;
  return s;
}

TEST(LightTreeRender, RendersTheSameExpectedImageAsPowerSelection) {
  // Per pixel, D = (tree estimate) - (power estimate) at the same spp; pixels are independent
  // and D has mean 0 where both are unbiased. Per 16 x 16 block and channel, the mean of D over
  // its standard error stays below the Bonferroni bound for all comparisons (false alarm 1e-3).
  // NEE cases check that a light the tree gives no chance from a point is left to BSDF rays.
  std::vector<RenderCase> all = {
      {"many-lights mis", shrunk("many-lights/scene.json", 48, 32), IntegratorType::kMis},
      {"many-lights nee", shrunk("many-lights/scene.json", 48, 32), IntegratorType::kNee},
      {"phong (quad and point light) mis", shrunk("phong/scene.json", 48, 32),
       IntegratorType::kMis},
      {"product (panel, spot, sky) nee", shrunk("product/scene.json", 48, 32),
       IntegratorType::kNee},
      {"small room (point light, glass, mirror)", testing::small_room_scene(48, 32),
       IntegratorType::kMis},
      // Enough samples that a light probability 1.3 times too high at BSDF hits shows (z > 5).
      {"room of large panels mis", panel_room(32, 32), IntegratorType::kMis, 512},
      {"room of large panels nee", panel_room(32, 32), IntegratorType::kNee, 64},
  };
  const uint32_t block = 16;
  size_t comparisons = 0;
  for (const RenderCase& c : all)
    comparisons += testing::blocks_compared(c.scene.film.width, c.scene.film.height, block);
  const double z_max = testing::bonferroni_z(comparisons);
  for (const RenderCase& c : all) {
    RenderSettings settings = c.scene.render;
    settings.integrator = c.integrator;
    settings.spp = c.spp;
    const std::vector<float> a = pixel_means(c.scene, settings, LightChoice::kTree, 5);
    const std::vector<float> b = pixel_means(c.scene, settings, LightChoice::kPower, 6);
    testing::expect_same_expectation(a, b, c.scene.film.width, c.scene.film.height, block, z_max,
                                     c.name);
  }
}

// Per-pixel variance of an estimate relative to the pixel's level, averaged over the image (as
// relMSE weighs errors): half the squared difference between two renders of different seeds
// over (their mean^2 + 0.01).
double mean_relative_variance(const Scene& scene, RenderSettings settings, LightChoice choice) {
  const std::vector<float> a = pixel_means(scene, settings, choice, 21);
  const std::vector<float> b = pixel_means(scene, settings, choice, 22);
  double s = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = double(a[i]) - b[i], m = 0.5 * (double(a[i]) + b[i]);
    s += 0.5 * d * d / (m * m + 0.01);
  }
  return s / double(a.size());
}

TEST(LightTreeRender, HasLessNoiseAmongManyLights) {
  // The hall of 64 lamps: from any point most lamps are far, and power selection spends most
  // samples on them. Each figure averages 4608 pixel channels (a few percent relative error);
  // the tree leaves about a quarter of the variance, far below the bound asked for.
  const Scene hall = shrunk("many-lights/scene.json", 48, 32);
  RenderSettings settings = hall.render;
  settings.spp = 8;
  const double tree = mean_relative_variance(hall, settings, LightChoice::kTree);
  const double power = mean_relative_variance(hall, settings, LightChoice::kPower);
  std::cout << "relative per-pixel variance at 8 spp: light tree " << tree << ", power " << power
            << " (ratio " << tree / power << ")\n";
  EXPECT_LT(tree, 0.5 * power);
  // And the renderer chooses the tree there by itself.
  EXPECT_NE(Renderer(hall, settings).plan().find("light tree"), std::string::npos);
  EXPECT_EQ(Renderer(shrunk("cornell-box/scene.json", 8, 8), settings).plan().find("light tree"),
            std::string::npos);
}

}  // namespace
}  // namespace rayfarm
