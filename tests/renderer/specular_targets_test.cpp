// Sampling towards specular objects (renderer/integrators/specular_targets.h): which objects are
// targets, and that the cone strategy's density is the one its samples follow. That the path
// tracer stays unbiased with it is integrators_test.cpp's (naive, which never aims, against NEE
// and MIS on the Cornell box with its mirror and glass spheres).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "common/scene/motion.h"
#include "tests/renderer/mc_stats.h"
#include "renderer/integrators/specular_targets.h"
#include "renderer/samplers/rng.h"

namespace rayfarm {
namespace {

Material diffuse() {
  Material m;
  m.kind = DiffuseMaterial{};
  return m;
}
Material mirror() {
  Material m;
  m.kind = MirrorMaterial{};
  return m;
}

// Materials 0 diffuse, 1 mirror; `specular` says which are specular, as the integrator does.
Scene two_material_scene() {
  Scene s;
  s.materials = {diffuse(), mirror()};
  return s;
}
const std::vector<bool> kSpecular{false, true};

TEST(SpecularTargets, SpecularSpheresAndMeshesOnly) {
  Scene s = two_material_scene();
  s.spheres.push_back({Vec3(0.f, 0.f, 0.f), 1.f, 0});  // diffuse: not a target
  s.spheres.push_back({Vec3(5.f, 0.f, 0.f), 2.f, 1});
  TriangleMesh mesh;  // two triangles, one of each material: the mirror one's bounds only
  mesh.positions = {Vec3(10, 0, 0), Vec3(12, 0, 0), Vec3(10, 2, 0), Vec3(-50, 0, 0)};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  mesh.materials = {1, 0};
  s.meshes.push_back(mesh);
  const SpecularTargets t = SpecularTargets::of_scene(s, kSpecular);
  ASSERT_EQ(t.targets().size(), 2u);
  EXPECT_NEAR(t.targets()[0].radius, 2.f, 1e-3f);  // largest first
  EXPECT_EQ(t.targets()[0].center, Vec3(5.f, 0.f, 0.f));
  const SpecularTarget& tri = t.targets()[1];
  for (const Vec3& v : {Vec3(10, 0, 0), Vec3(12, 0, 0), Vec3(10, 2, 0)})
    EXPECT_LE(length(v - tri.center), tri.radius) << "a vertex outside its bounding sphere";
  EXPECT_LT(tri.radius, 2.f);  // the diffuse triangle's far vertex is not in it
}

TEST(SpecularTargets, InstancesArePlacedAndTheLargestKept) {
  Scene s = two_material_scene();
  MeshGroup g;
  TriangleMesh mesh;
  mesh.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  mesh.indices = {0, 1, 2};
  mesh.materials = {1};
  g.meshes.push_back(mesh);
  s.groups.push_back(g);
  // Twelve placements, scaled 1..12 and moved 100 apart: the 8 largest are kept.
  for (int i = 1; i <= 12; ++i) {
    Instance inst;
    inst.world_from_object = {double(i), 0, 0, 100.0 * i, 0, double(i), 0, 0, 0, 0, double(i), 0,
                              0, 0, 0, 1};
    s.instances.push_back(inst);
  }
  const SpecularTargets t = SpecularTargets::of_scene(s, kSpecular);
  ASSERT_EQ(t.targets().size(), size_t(SpecularTargets::kMaxTargets));
  for (size_t k = 0; k < t.targets().size(); ++k) {
    const float scale = static_cast<float>(12 - k);
    const SpecularTarget& target = t.targets()[k];
    for (const Vec3& v : {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)})
      EXPECT_LE(length(v * scale + Vec3(100.f * scale, 0.f, 0.f) - target.center), target.radius);
  }
}

TEST(SpecularTargets, WhatMovesIsLeftOut) {
  Scene s = two_material_scene();
  s.spheres.push_back({Vec3(5.f, 0.f, 0.f), 2.f, 1});
  s.spheres.push_back({Vec3(-5.f, 0.f, 0.f), 1.f, 1});
  auto motion = std::make_shared<SceneMotion>();
  s.motion = motion;  // a shutter, nothing moving
  EXPECT_EQ(SpecularTargets::of_scene(s, kSpecular).targets().size(), 2u);
  motion->spheres.push_back({0, {s.spheres[0], s.spheres[0]}});
  const SpecularTargets t = SpecularTargets::of_scene(s, kSpecular);
  ASSERT_EQ(t.targets().size(), 1u);
  EXPECT_EQ(t.targets()[0].center, Vec3(-5.f, 0.f, 0.f));
}

TEST(SpecularTargets, ConesSkipTargetsAroundThePointAndBelowItsSurface) {
  const SpecularTargets t({{Vec3(0.f, 0.f, 5.f), 1.f}, {Vec3(0.f, 0.f, -5.f), 1.f},
                           {Vec3(0.5f, 0.f, 0.f), 2.f}});
  TargetCones cones;
  t.cones(Vec3(0.f), Vec3(0.f), cones);  // inside the third: two cones
  EXPECT_EQ(cones.count, 2u);
  t.cones(Vec3(0.f), Vec3(0.f, 0.f, 1.f), cones);  // the one below the surface too
  ASSERT_EQ(cones.count, 1u);
  EXPECT_EQ(cones.axis(0), Vec3(0.f, 0.f, 1.f));
  EXPECT_NEAR(cones.total, 2.0 * kPi * (1.0 - std::sqrt(1.0 - 1.0 / 25.0)), 1e-6);
  // A target too small to resolve from afar is not aimed at.
  const SpecularTargets far({{Vec3(0.f, 0.f, 40.f), 1.f}});
  far.cones(Vec3(0.f), Vec3(0.f), cones);
  EXPECT_EQ(cones.count, 0u);
  // A cone that reaches above the plane stays, though its axis points below it.
  const SpecularTargets low({{Vec3(4.f, 0.f, -0.5f), 1.f}});
  low.cones(Vec3(0.f), Vec3(0.f, 0.f, 1.f), cones);
  EXPECT_EQ(cones.count, 1u);
}

// Overlapping cones of different sizes, near and far: the samples follow pdf().
TEST(SpecularTargets, SamplesFollowTheirDensity) {
  const SpecularTargets t({{Vec3(0.f, 0.f, 3.f), 1.f},
                           {Vec3(0.6f, 0.f, 3.f), 0.8f},
                           {Vec3(-14.f, 2.f, 1.f), 0.5f},
                           {Vec3(0.f, -1.3f, 0.f), 1.2f}});
  TargetCones cones;
  t.cones(Vec3(0.f), Vec3(0.f), cones);
  ASSERT_EQ(cones.count, 4u);
  Pcg32 rng = sample_stream(7, 0, 0);
  const int n = 400000;
  // E[1{w in cone k} / pdf(w)] is cone k's solid angle, whatever the overlaps.
  std::vector<double> sum(cones.count, 0.0), sum2(cones.count, 0.0);
  for (int i = 0; i < n; ++i) {
    const Vec3 w = SpecularTargets::sample(cones, rng.next_float(), rng.next_float(),
                                           rng.next_float());
    ASSERT_NEAR(length(w), 1.f, 1e-5f);
    const float pdf = cones.pdf(w);
    ASSERT_GT(pdf, 0.f) << "a sample outside every cone";
    for (uint32_t k = 0; k < cones.count; ++k) {
      const double v = dot(w, cones.axis(k)) >= cones.cos_max[k] ? 1.0 / pdf : 0.0;
      sum[k] += v;
      sum2[k] += v * v;
    }
  }
  const double z = testing::bonferroni_z(cones.count);
  for (uint32_t k = 0; k < cones.count; ++k) {
    const double mean = sum[k] / n;
    const double se = std::sqrt((sum2[k] / n - mean * mean) / (n - 1));
    const double exact = 2.0 * kPi * cones.one_minus_cos[k];
    EXPECT_NEAR(mean, exact, z * se + 1e-6 * exact) << "cone " << k;
  }
  // The narrowest cone aimed at holds its own samples (membership is decided in float).
  const float d = 1.f / std::sqrt(SpecularTargets::kMinSin2) * 0.99f;
  const SpecularTargets narrow({{Vec3(0.3f, -0.2f, 1.f) * (d / length(Vec3(0.3f, -0.2f, 1.f))),
                                 1.f}});
  TargetCones thin;
  narrow.cones(Vec3(0.f), Vec3(0.f), thin);
  ASSERT_EQ(thin.count, 1u);
  int outside = 0;
  for (int i = 0; i < n; ++i)
    outside += !(thin.pdf(SpecularTargets::sample(thin, rng.next_float(), rng.next_float(),
                                                  rng.next_float())) > 0.f);
  EXPECT_LE(outside, n / 1000) << "samples of a narrow cone judged outside it";
  // And pdf() integrates to 1 over the sphere (uniform directions, 1 / (4 pi) each).
  double total = 0.0, total2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const float zc = 1.f - 2.f * rng.next_float();
    const float r = std::sqrt(std::max(0.f, 1.f - zc * zc)), phi = 2.f * kPi * rng.next_float();
    const double v = 4.0 * kPi * cones.pdf(Vec3(r * std::cos(phi), r * std::sin(phi), zc));
    total += v;
    total2 += v * v;
  }
  const double mean = total / n;
  const double se = std::sqrt((total2 / n - mean * mean) / (n - 1));
  EXPECT_NEAR(mean, 1.0, testing::bonferroni_z(1) * se);
}

}  // namespace
}  // namespace rayfarm
