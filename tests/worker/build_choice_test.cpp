// Which scenes the BVH is built for per geometry (worker/embree/build_choice.h): rooms whose walls
// are geometries of their own, with objects that keep to their own space, and not geometries that
// share space. That the two-level tree finds the same hits is every render test's: the bundled
// Cornell scenes and the test scenes are built that way now (and render the same bits as before).
#include <gtest/gtest.h>

#include <limits>
#include <vector>

#include "worker/embree/build_choice.h"

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
