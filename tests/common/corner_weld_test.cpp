// Welding of OBJ face corners: equal (v, t, n) corners share a vertex, vertices are numbered by
// first use, and the work stays O(n log n) comparisons on corners chosen to collide in the
// packed-integer hash that a hash-map weld would use.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <tuple>
#include <utility>
#include <vector>

#include "common/scene/corner_weld.h"

namespace rayfarm {
namespace {

constexpr uint32_t kNone = UINT32_MAX;

/// The welding as a plain ordered map does it, for reference.
WeldedCorners weld_with_map(const std::vector<CornerIndices>& corners) {
  std::map<std::tuple<uint32_t, uint32_t, uint32_t>, uint32_t> seen;
  WeldedCorners out;
  for (uint32_t i = 0; i < corners.size(); ++i) {
    const auto [it, added] = seen.try_emplace(std::tie(corners[i].v, corners[i].t, corners[i].n),
                                              static_cast<uint32_t>(out.first_corner.size()));
    if (added) out.first_corner.push_back(i);
    out.vertex_of.push_back(it->second);
  }
  return out;
}

TEST(CornerWeld, EqualCornersShareAVertexNumberedByFirstUse) {
  const std::vector<CornerIndices> corners = {{5, 1, 2},     {3, 4, kNone}, {5, 1, 2},
                                              {5, 1, kNone}, {0, 0, 0},     {3, 4, kNone}};
  const WeldedCorners w = weld_corners(corners);
  EXPECT_EQ(w.vertex_of, (std::vector<uint32_t>{0, 1, 0, 2, 3, 1}));
  EXPECT_EQ(w.first_corner, (std::vector<uint32_t>{0, 1, 3, 4}));
  EXPECT_TRUE(weld_corners({}).vertex_of.empty());
}

/// Corners whose packed key (v << 32) ^ (t * golden ratio) ^ n is the same 64-bit number for all
/// of them: in a hash map keyed that way every lookup would walk one chain of all of them. Each
/// key appears `repeats` times, in an order that interleaves the repeats.
std::vector<CornerIndices> colliding_corners(uint32_t distinct, uint32_t repeats) {
  constexpr uint64_t kGolden = 0x9e3779b97f4a7c15ull;
  std::vector<CornerIndices> keys;
  for (uint32_t t = 0; t < distinct; ++t) {
    const uint64_t mixed = uint64_t{t} * kGolden;
    keys.push_back(
        {static_cast<uint32_t>(mixed >> 32) ^ 0x1234u, t, static_cast<uint32_t>(mixed) ^ 0x5678u});
  }
  std::vector<CornerIndices> corners;
  for (uint32_t r = 0; r < repeats; ++r) {
    for (uint32_t k = 0; k < distinct; ++k) corners.push_back(keys[(k * 7919u + r) % distinct]);
  }
  return corners;
}

TEST(CornerWeld, CollidingCornersTakeNLogNComparisons) {
  const uint32_t distinct = 1u << 15, repeats = 4;
  const std::vector<CornerIndices> corners = colliding_corners(distinct, repeats);
  const auto key = [](const CornerIndices& c) {
    return (uint64_t{c.v} << 32) ^ (uint64_t{c.t} * 0x9e3779b97f4a7c15ull) ^ c.n;
  };
  for (const CornerIndices& c : corners) ASSERT_EQ(key(c), key(corners[0])) << "not colliding";

  uint64_t comparisons = 0;
  const WeldedCorners w = weld_corners(corners, &comparisons);
  const WeldedCorners expected = weld_with_map(corners);
  EXPECT_EQ(w.vertex_of, expected.vertex_of);
  EXPECT_EQ(w.first_corner, expected.first_corner);
  EXPECT_EQ(w.first_corner.size(), distinct);
  // A chained hash map would make about n^2 / 2 = 8.6e9 key steps here; sorting n = 131072
  // corners takes about 1.4 n log2 n, bounded here by 3 n log2 n = 6.7e6.
  const double n = static_cast<double>(corners.size());
  EXPECT_LE(static_cast<double>(comparisons), 3.0 * n * std::log2(n)) << comparisons;
  EXPECT_GT(comparisons, 0u);
}

TEST(CornerWeld, AllEqualAndAllDistinctCornersStayNLogN) {
  const size_t n = 1u << 16;
  const std::vector<CornerIndices> same(n, CornerIndices{1, 2, 3});
  std::vector<CornerIndices> distinct;
  for (uint32_t i = 0; i < n; ++i) distinct.push_back({static_cast<uint32_t>(n) - i, kNone, i});
  for (const std::vector<CornerIndices>* corners : {&same, &std::as_const(distinct)}) {
    uint64_t comparisons = 0;
    const WeldedCorners w = weld_corners(*corners, &comparisons);
    EXPECT_EQ(w.vertex_of, weld_with_map(*corners).vertex_of);
    EXPECT_LE(static_cast<double>(comparisons), 3.0 * n * std::log2(double(n))) << comparisons;
  }
}

}  // namespace
}  // namespace rayfarm
