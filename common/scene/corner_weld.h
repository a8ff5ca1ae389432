#pragma once
// Welding of mesh corners that share a position, texture coordinate and normal index into one
// vertex (the OBJ reader's). By sorting rather than hashing: the indices come from the file, and
// a file could choose them to collide in any fixed hash, making each lookup walk a chain as long
// as the mesh. Sorting takes O(n log n) comparisons whatever the indices are.
#include <cstdint>
#include <span>
#include <vector>

namespace rayfarm {

/// The indices of one face corner (UINT32_MAX where the file gives none).
struct CornerIndices {
  uint32_t v, t, n;
  bool operator==(const CornerIndices&) const = default;
};

struct WeldedCorners {
  /// Per corner: its vertex. Vertices are numbered in the order of their first corner.
  std::vector<uint32_t> vertex_of;
  /// Per vertex: the first corner that uses it.
  std::vector<uint32_t> first_corner;
};

/// Welds equal corners. `comparisons`, when given, receives how many key comparisons it made.
WeldedCorners weld_corners(std::span<const CornerIndices> corners, uint64_t* comparisons = nullptr);

}  // namespace rayfarm
