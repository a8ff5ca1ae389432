#pragma once
// Light selection that follows the shading point: a binary tree over the lights that have a
// place (emissive triangles and spheres, point and spot lights), each node holding the bounds of
// its lights (light_bounds.h). A choice walks down from the root, taking each child with
// probability proportional to its importance at the point; the probability of a light is the
// product along its path, recomputed the same way (same order, same rounding) when a BSDF ray
// finds the light, so that both strategies' MIS weights agree to the bit.
//
// Built by a binned surface-area-orientation heuristic: splits that keep near lights together and
// lights facing alike together, one light per leaf. The build depends only on the lights, so
// every worker builds the same tree.
#include <cstdint>
#include <vector>

#include "renderer/lights/light_bounds.h"

namespace rayfarm {

class LightTree {
 public:
  LightTree() = default;
  /// One entry per light: its bounds and its index among the scene's lights (at most 2^32 - 1
  /// entries; intensities > 0).
  LightTree(const std::vector<LightBounds>& bounds, const std::vector<int32_t>& lights);

  bool empty() const { return nodes_.empty(); }
  /// Nodes, leaves included (2 x lights - 1).
  size_t node_count() const { return nodes_.size(); }
  /// Longest path from the root to a leaf, in edges (at most kMaxDepth).
  uint32_t depth() const { return depth_; }
  static constexpr uint32_t kMaxDepth = 64;

  /// Chooses a light for the point p with normal n (or zero) from the uniform number u in
  /// [0, 1); sets its probability. False when no light can reach p (every importance 0).
  bool choose(const Vec3& p, const Vec3& n, double u, int32_t& light, float& probability) const;
  /// Probability that choose() at (p, n) returns `light`; 0 for a light not in the tree.
  float probability(const Vec3& p, const Vec3& n, int32_t light) const;

 private:
  struct Node {
    ImportanceBounds bounds;
    uint32_t second = 0;  ///< interior: the second child (the first follows the node)
    int32_t light = -1;   ///< leaf: the light's index; interior: -1
  };
  struct Path {
    uint64_t turns = 0;  ///< bit d: the second child was taken at depth d
    uint32_t length = 0;
    bool present = false;
  };

  /// Builds the subtree of lights order[begin, end) as the next nodes; returns its bounds.
  LightBounds build(std::vector<uint32_t>& order, uint32_t begin, uint32_t end, uint32_t depth,
                    uint64_t turns, const std::vector<LightBounds>& bounds,
                    const std::vector<int32_t>& lights);
  /// Probability of taking the first child of interior node `node` at (p, n), as a float.
  float first_share(uint32_t node, const Vec3& p, const Vec3& n) const;

  std::vector<Node> nodes_;
  std::vector<Path> paths_;        // by light index
  uint32_t depth_ = 0;
};

}  // namespace rayfarm
