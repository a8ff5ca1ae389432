// Instanced meshes: traced through one shared BVH per group, they render as the same meshes
// placed in the world by hand (within the noise), their triangles are stored once, and a
// mirrored placement keeps its normals outward.
#include <gtest/gtest.h>

#include "common/scene/instances.h"
#include "mc_stats.h"
#include "test_scenes.h"
#include "renderer/renderer.h"
#include "renderer/scene_data.h"

namespace rayfarm {
namespace {

// Two quads at right angles, with vertex normals, in object space.
TriangleMesh prism(uint32_t material) {
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {0.3f, 0, 0}, {0.3f, 0.3f, 0}, {0, 0.3f, 0},
                 {0, 0, 0}, {0, 0.3f, 0}, {0, 0.3f, 0.3f}, {0, 0, 0.3f}};
  m.normals = {{0, 0, -1}, {0, 0, -1}, {0.3f, 0, -0.95f}, {0, 0, -1},
               {-1, 0, 0}, {-1, 0, 0}, {-0.95f, 0.3f, 0}, {-1, 0, 0}};
  for (Vec3& n : m.normals) n = n / length(n);
  m.indices = {0, 2, 1, 0, 3, 2, 4, 6, 5, 4, 7, 6};
  m.materials.assign(4, material);
  return m;
}

std::array<double, 16> rows(const Transform& t) {
  std::array<double, 16> m{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m[4 * r + c] = t.at(r, c);
  m[15] = 1.0;
  return m;
}

// The small room with three prisms: placed by instances of one group, or by hand.
struct Pair {
  Scene instanced, by_hand;
};

Pair room_with_prisms() {
  Pair p{testing::small_room_scene(), testing::small_room_scene()};
  const TriangleMesh box = prism(2);  // the room's phong material
  const Transform placements[] = {
      Transform::translate({-0.6, 0.2, -0.4}),
      Transform::rotate({0, 1, 0}, 30).then(Transform::translate({0.2, 0.1, 0.0})),
      Transform::scale({-1.5, 1, 1}).then(Transform::translate({0.7, -0.2, -0.5})),  // mirror
  };
  p.instanced.groups.push_back({"prism", {box}});
  for (const Transform& t : placements) {
    p.instanced.instances.push_back({0, rows(t)});
    p.by_hand.meshes.push_back(place_mesh(box, t));
  }
  return p;
}

// Independent renders (different seeds) of both, compared block by block: each difference
// within the Bonferroni bound of all the blocks and channels of every integrator (1e-3 overall).
TEST(InstanceRender, InstancesRenderAsTheirMeshesPlacedByHand) {
  const Pair p = room_with_prisms();
  const IntegratorType integrators[] = {IntegratorType::kNaive, IntegratorType::kNee,
                                        IntegratorType::kMis};
  const size_t family = 3 * (24 / 4) * (16 / 4) * 3;
  for (IntegratorType integrator : integrators) {
    const testing::BlockStats a = testing::render_blocks(p.instanced, integrator, 256, 1, 4);
    const testing::BlockStats b = testing::render_blocks(p.by_hand, integrator, 256, 2, 4);
    testing::expect_same_within_noise(a, b, integrator_name(integrator), family);
  }
  RenderSettings settings = p.instanced.render;
  const Renderer renderer(p.instanced, settings);
  EXPECT_NE(renderer.plan().find("3 instances of 1 groups"), std::string::npos) << renderer.plan();
}

// The prototype's triangles are stored once however often it is placed.
TEST(InstanceRender, GroupTrianglesAreStoredOnce) {
  const Pair p = room_with_prisms();
  const SceneData instanced(p.instanced), by_hand(p.by_hand);
  const size_t room = p.by_hand.meshes[0].triangle_count();
  EXPECT_EQ(instanced.instances(), 3u);
  EXPECT_EQ(instanced.stored_triangles(), room + 4);
  EXPECT_EQ(by_hand.stored_triangles(), room + 3 * 4);
}

// A triangle facing +z at z = 1, mirrored in z: the placed surface at z = -1 faces -z, and so do
// its geometric and shading normals at the hit (the flat one bit for bit).
TEST(InstanceRender, MirroredInstanceNormalsPointOutward) {
  for (bool smooth : {false, true}) {
    Scene scene;
    scene.film = {4, 4};
    scene.materials.push_back(Material{});
    TriangleMesh tri;
    tri.positions = {{-1, -1, 1}, {1, -1, 1}, {0, 1, 1}};
    if (smooth) tri.normals = {{0.1f, 0, 0.995f}, {0, 0, 1}, {0, 0, 1}};
    tri.indices = {0, 1, 2};
    tri.materials = {0};
    scene.groups.push_back({"t", {tri}});
    scene.instances.push_back({0, rows(Transform::scale({1, 1, -1}))});
    const SceneData data(scene);
    const Ray ray{{0.f, 0.f, -5.f}, {0.f, 0.f, 1.f}};
    const std::optional<RayHit> hit = data.bvh().intersect(ray);
    ASSERT_TRUE(hit);
    EXPECT_EQ(hit->inst, 0u);
    const SurfaceHit s = data.resolve(ray, *hit);
    EXPECT_NEAR(s.p.z, -1.f, 1e-6f);
    EXPECT_NEAR(s.n.z, -1.f, 1e-6f);
    EXPECT_LT(s.ns.z, -0.99f);
    if (!smooth) {
      EXPECT_TRUE(s.ns == s.n);
    }
  }
}

}  // namespace
}  // namespace rayfarm
