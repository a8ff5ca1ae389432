// The contract everything rests on: a sample's random numbers depend only on (seed, pixel,
// sample index) and merging is exact, so tiles, passes, threads and merge order never change
// a single bit of the image.
#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <algorithm>
#include <random>
#include <stdexcept>

#include "mc_stats.h"
#include "test_scenes.h"
#include "renderer/renderer.h"
#include "renderer/scene_data.h"
#include "tests/support/tile_result_compare.h"

namespace rayfarm {
namespace {

void expect_identical(const Film& a, const Film& b) {
  ASSERT_EQ(a.width(), b.width());
  ASSERT_EQ(a.height(), b.height());
  EXPECT_TRUE(a.sum() == b.sum()) << "sums differ";
  EXPECT_TRUE(a.sum_sq() == b.sum_sq()) << "squared sums differ";
  EXPECT_EQ(a.spp(), b.spp());
  EXPECT_EQ(a.rays(), b.rays());
  EXPECT_EQ(a.mean_rgb(), b.mean_rgb());
}

class DeterminismTest : public ::testing::TestWithParam<IntegratorType> {};

TEST_P(DeterminismTest, ThreadsTilesAndPassesDoNotChangeTheImage) {
  const Scene scene = testing::small_room_scene();
  RenderSettings settings = scene.render;
  settings.integrator = GetParam();
  settings.spp = 12;
  settings.seed = 42;
  Renderer renderer(scene, settings);
  const Film reference = testing::render_with(renderer, 1, 64, 12);
  expect_identical(reference, testing::render_with(renderer, 2, 64, 12));
  expect_identical(reference, testing::render_with(renderer, 2, 16, 4));
  expect_identical(reference, testing::render_with(renderer, 1, 7, 5));
  EXPECT_GT(reference.rays(), 0u);
}

INSTANTIATE_TEST_SUITE_P(AllIntegrators, DeterminismTest,
                         ::testing::Values(IntegratorType::kNaive, IntegratorType::kNee,
                                           IntegratorType::kMis),
                         [](const auto& test_info) {
                           return std::string(integrator_name(test_info.param));
                         });

TEST(Determinism, ShuffledUnitsMergeToTheSameBits) {
  const Scene scene = testing::small_room_scene();
  RenderSettings settings = scene.render;
  settings.spp = 8;
  Renderer renderer(scene, settings);
  std::vector<std::pair<TileRect, SampleRange>> units;
  for (const TileRect& t : split_tiles(scene.film, 8)) {
    for (const SampleRange& p : split_passes(settings.spp, 3)) units.emplace_back(t, p);
  }
  Film in_order(scene.film.width, scene.film.height);
  for (const auto& [t, p] : units) in_order.add(renderer.render(t, p));
  std::mt19937 shuffle_rng(3);
  std::shuffle(units.begin(), units.end(), shuffle_rng);
  Film shuffled(scene.film.width, scene.film.height);
  for (const auto& [t, p] : units) shuffled.add(renderer.render(t, p));
  expect_identical(in_order, shuffled);
}

// Rendering into a kept result (as local renders do, unit after unit) gives the bits and counts
// of a fresh one, whichever unit, larger or smaller, it held before.
TEST(Determinism, RenderingIntoAKeptResultGivesAFreshOnesBits) {
  const Scene scene = testing::small_room_scene();
  RenderSettings settings = scene.render;
  settings.spp = 6;
  Renderer renderer(scene, settings);
  TileResult kept;
  const std::vector<std::pair<TileRect, SampleRange>> units = {
      {{0, 0, 16, 16}, {0, 3}}, {{3, 5, 9, 7}, {3, 6}}, {{8, 0, 16, 12}, {1, 5}}};
  for (const auto& [t, p] : units) {
    renderer.render(t, p, kept);
    testing::expect_same_result(kept, renderer.render(t, p));
    EXPECT_GT(kept.rays, 0u);
  }
}

TEST(Determinism, SeedChangesTheImage) {
  const Scene scene = testing::small_room_scene();
  RenderSettings a = scene.render, b = scene.render;
  a.spp = b.spp = 4;
  b.seed = a.seed + 1;
  const Film fa = testing::render_with(Renderer(scene, a), 1, 64, 4);
  const Film fb = testing::render_with(Renderer(scene, b), 1, 64, 4);
  EXPECT_FALSE(fa.sum() == fb.sum());
}

// The benchmark's diffuse-only renderer (bench/diffuse_only.sh) measures the same work: on a
// diffuse scene it renders the normal renderer's bits, and it refuses any other scene.
TEST(Determinism, DiffuseOnlyRendererRendersTheSameBits) {
  const Scene scene = testing::furnace_scene(0.5f, 1.f, 8);
  RenderSettings settings = scene.render;
  settings.spp = 4;
  settings.max_depth = 8;
  const Film all = testing::render_with(Renderer(scene, settings), 1, 64, 4);
  const Film diffuse =
      testing::render_with(Renderer(scene, settings, BsdfKinds::kDiffuseOnly), 1, 64, 4);
  expect_identical(all, diffuse);
  EXPECT_THROW(Renderer(testing::small_room_scene(), settings, BsdfKinds::kDiffuseOnly),
               std::runtime_error);
}

// A scene of the kinds without microfacets renders through the four-kind BSDF (inlined
// dispatch); the nine-kind one must give the same bits, under every integrator.
TEST(Determinism, BasicKindsRendererRendersTheSameBits) {
  for (IntegratorType integrator :
       {IntegratorType::kNaive, IntegratorType::kNee, IntegratorType::kMis}) {
    const Scene scene = testing::small_room_scene();  // diffuse, phong, mirror, glass, emitter
    RenderSettings settings = scene.render;
    settings.spp = 4;
    settings.integrator = integrator;
    const Film basic = testing::render_with(Renderer(scene, settings), 1, 64, 4);
    const Film every =
        testing::render_with(Renderer(scene, settings, BsdfKinds::kEveryKind), 1, 64, 4);
    expect_identical(basic, every);
  }
}

// A flat, untextured scene runs the path loop that leaves out every test for shading normals,
// texture coordinates and surface features (PathMode::kPlain). An unused material that reads a
// texture sends the same scene through the general loop, one with a bump map through the
// surface loop: all three must give the same bits, under every integrator.
TEST(Determinism, PlainGeneralAndSurfaceLoopsRenderTheSameBits) {
  const Scene plain = testing::small_room_scene();  // quads and spheres, no vertex normals
  TextureDesc checker;
  checker.name = "checker";
  checker.kind = TextureDesc::Kind::kCheckerboard;
  Scene general = plain;
  general.textures.push_back(checker);
  Material textured;
  textured.name = "unused textured emitter";
  textured.emission.value = Vec3(1.f);
  textured.emission.texture = 0;
  general.materials.push_back(textured);
  Scene surface = plain;
  surface.textures.push_back(checker);
  Material bumped;
  bumped.name = "unused bump-mapped";
  bumped.bump_map = BumpMap{0, 0.1f};
  surface.materials.push_back(bumped);
  EXPECT_TRUE(SceneData(plain).plain());
  EXPECT_FALSE(SceneData(general).plain());
  EXPECT_FALSE(SceneData(surface).plain());
  EXPECT_TRUE(SceneData(surface).uses_surface());
  for (IntegratorType integrator :
       {IntegratorType::kNaive, IntegratorType::kNee, IntegratorType::kMis}) {
    RenderSettings settings = plain.render;
    settings.spp = 4;
    settings.integrator = integrator;
    const Film reference = testing::render_with(Renderer(plain, settings), 1, 64, 4);
    expect_identical(reference, testing::render_with(Renderer(general, settings), 1, 64, 4));
    expect_identical(reference, testing::render_with(Renderer(surface, settings), 1, 64, 4));
  }
}

}  // namespace
}  // namespace rayfarm
