// Which scenes the BVH is built for per geometry (renderer/embree/build_choice.h): rooms whose walls
// are geometries of their own, with objects that keep to their own space, and not geometries that
// share space. That the two-level tree finds the same hits is every render test's: the bundled
// Cornell scenes and the test scenes are built that way now (and render the same bits as before).
#include <gtest/gtest.h>

#include <limits>
#include <optional>
#include <vector>

#include "renderer/embree/bvh.h"
#include "renderer/embree/build_choice.h"

namespace rayfarm {
namespace {

BuildBox box(Vec3 lo, Vec3 hi) {
  BuildBox b;
  b.add(lo);
  b.add(hi);
  return b;
}

// The Cornell box's five walls as flat boxes (each wall a geometry of its own).
std::vector<BuildBox> walls() {
  return {box({0, 0, 0}, {556, 0, 559}),     box({0, 549, 0}, {556, 549, 559}),
          box({0, 0, 559}, {556, 549, 559}), box({0, 0, 0}, {0, 549, 559}),
          box({556, 0, 0}, {556, 549, 559})};
}

TEST(BuildChoice, RoomWithObjectsIsBuiltApart) {
  std::vector<BuildBox> boxes = walls();
  EXPECT_TRUE(build_geometries_apart(boxes));
  boxes.push_back(box({85, 0, 70}, {285, 200, 270}));    // a sphere of 40k triangles
  boxes.push_back(box({250, 30, 250}, {490, 270, 490}));  // and another, touching it
  EXPECT_TRUE(build_geometries_apart(boxes));
}

TEST(BuildChoice, GeometriesSharingSpaceAreBuiltAsOne) {
  // Two meshes scattered through the whole room: a ray would descend both trees.
  std::vector<BuildBox> boxes = walls();
  boxes.push_back(box({20, 5, 20}, {530, 500, 540}));
  boxes.push_back(box({25, 8, 21}, {528, 505, 535}));
  EXPECT_FALSE(build_geometries_apart(boxes));
  // Alone, too.
  EXPECT_FALSE(build_geometries_apart({boxes[5], boxes[6]}));
}

TEST(BuildChoice, CoplanarOverlapsCountByArea) {
  // Ten flat meshes over the same square: no volume, but the padding makes them count.
  std::vector<BuildBox> boxes(10, box({0, 0, 0}, {100, 0, 100}));
  EXPECT_FALSE(build_geometries_apart(boxes));
  // Two flat meshes with a gap between them do not overlap.
  EXPECT_TRUE(build_geometries_apart({box({0, 0, 0}, {40, 0, 100}), box({60, 0, 0}, {100, 0, 100})}));
}

TEST(BuildChoice, FewerThanTwoGeometriesOrDegenerateBoxesKeepOneTree) {
  EXPECT_FALSE(build_geometries_apart({}));
  EXPECT_FALSE(build_geometries_apart({box({0, 0, 0}, {1, 1, 1})}));
  // Empty boxes (a mesh without triangles) do not count as geometries.
  EXPECT_FALSE(build_geometries_apart({box({0, 0, 0}, {1, 1, 1}), BuildBox{}, BuildBox{}}));
  // Every geometry at one point: no extent to compare volumes in.
  EXPECT_FALSE(build_geometries_apart({box({1, 2, 3}, {1, 2, 3}), box({1, 2, 3}, {1, 2, 3})}));
  // Coordinates whose differences overflow to infinity.
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_FALSE(build_geometries_apart({box({-inf, 0, 0}, {0, 1, 1}), box({0, 0, 0}, {1, 1, 1})}));
  EXPECT_FALSE(
      build_geometries_apart({box({-3e38f, 0, 0}, {0, 1, 1}), box({0, 0, 0}, {3e38f, 1, 1})}));
}

}  // namespace
}  // namespace rayfarm

namespace rayfarm {
namespace {

// Where two geometries' surfaces coincide, a ray meets both at exactly the same distance and
// reports whichever the tree's traversal finds first. The two-level build must make that the
// same tree on every build (every worker, every run), or farm images could differ from local ones
// in such pixels.
TEST(BuildChoice, CoincidentSurfacesReportTheSameHitOnEveryBuild) {
  // 32 tiles apart from each other on a plane, each there twice (two geometries).
  std::vector<std::vector<Vec3>> positions;
  const std::vector<uint32_t> indices{0, 1, 2, 0, 2, 3};
  for (int copy = 0; copy < 2; ++copy) {
    for (int i = 0; i < 32; ++i) {
      const float x = 20.f * float(i % 8), z = 20.f * float(i / 8);
      positions.push_back({{x, 0, z}, {x + 10, 0, z}, {x + 10, 0, z + 10}, {x, 0, z + 10}});
    }
  }
  std::vector<Bvh::Mesh> meshes;
  std::vector<BuildBox> boxes;
  for (const std::vector<Vec3>& p : positions) {
    meshes.push_back(Bvh::Mesh{&p, &indices});
    BuildBox b;
    for (const Vec3& v : p) b.add(v);
    boxes.push_back(b);
  }
  ASSERT_TRUE(build_geometries_apart(boxes));  // the build this test is about
  const auto hits = [&] {
    const Bvh bvh(meshes, {});
    std::vector<uint32_t> found;
    for (int i = 0; i < 32; ++i) {
      for (float u : {2.5f, 5.f, 7.5f}) {
        const Ray ray{Vec3(20.f * float(i % 8) + u, 5.f, 20.f * float(i / 8) + 10.f - u),
                      Vec3(0.f, -1.f, 0.f)};
        const std::optional<RayHit> hit = bvh.intersect(ray);
        found.push_back(hit ? hit->geom * 2 + hit->prim : UINT32_MAX);
      }
    }
    return found;
  };
  const std::vector<uint32_t> first = hits();
  for (uint32_t h : first) EXPECT_NE(h, UINT32_MAX);
  for (int build = 0; build < 30; ++build) ASSERT_EQ(hits(), first) << "build " << build;
}

}  // namespace
}  // namespace rayfarm
