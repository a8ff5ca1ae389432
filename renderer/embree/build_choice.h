#pragma once
// How the BVH of a scene (or of an instanced group) is built: one tree over every primitive of
// every geometry, or a tree per geometry under one tree over those (Embree's two-level build).
//
// The single tree is binned by triangle centroids. Where a few triangles are far larger than the
// rest (a room's walls, floor and ceiling: a handful of triangles whose boxes span the scene), they
// land in bins beside the small ones and swell the boxes of every node above them, so that most
// rays open most of the tree; spatial splits (Embree's high quality) cut them only within a
// budget. Apart, each geometry's tree stays tight and the walls' trees are a leaf or two. The
// two-level build costs where geometries overlap: a ray descends every tree whose box it crosses,
// so two meshes interleaved through the same space cost about twice one merged tree, and hundreds
// of them hundreds of times (docs/benchmarks.md, "The BVH built per geometry").
//
// The rule: apart when there are at least two geometries and their boxes together hold no more
// volume than the box around all of them, i.e. a point of the scene lies inside one geometry's box
// on average at most. Boxes are padded by 1% of the scene's largest extent first, so that flat
// geometries (a wall, a floor tile) count by their area: coplanar ones that overlap still add up.
// A function of the geometry alone, so every worker builds the same tree and finds the same hits.
#include <algorithm>
#include <cmath>
#include <vector>

#include "common/math/vec3.h"

namespace rayfarm {

/// An axis-aligned box; empty (lo > hi) until a point is added.
struct BuildBox {
  Vec3 lo{3.0e38f, 3.0e38f, 3.0e38f};
  Vec3 hi{-3.0e38f, -3.0e38f, -3.0e38f};

  bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  void add(const Vec3& p) {
    lo = Vec3(std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z));
    hi = Vec3(std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z));
  }
  void add(const BuildBox& b) {
    if (b.empty()) return;
    add(b.lo);
    add(b.hi);
  }
};

/// Whether the geometries whose boxes are `boxes` are better built apart (the two-level build)
/// than as one tree; see above. Empty boxes are ignored; false for fewer than two, and for boxes
/// that are not finite.
inline bool build_geometries_apart(const std::vector<BuildBox>& boxes) {
  BuildBox all;
  size_t count = 0;
  for (const BuildBox& b : boxes) {
    if (b.empty()) continue;
    all.add(b);
    ++count;
  }
  if (count < 2) return false;
  const double extent = std::max({double(all.hi.x) - all.lo.x, double(all.hi.y) - all.lo.y,
                                  double(all.hi.z) - all.lo.z});
  if (!std::isfinite(extent) || !(extent > 0.0)) return false;
  const double pad = 0.02 * extent;  // 1% on each side
  const auto volume = [pad](const BuildBox& b) {
    return (double(b.hi.x) - b.lo.x + pad) * (double(b.hi.y) - b.lo.y + pad) *
           (double(b.hi.z) - b.lo.z + pad);
  };
  double sum = 0.0;
  for (const BuildBox& b : boxes) {
    if (!b.empty()) sum += volume(b);
  }
  return sum <= volume(all);
}

}  // namespace rayfarm
