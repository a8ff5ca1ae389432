#include "common/scene/corner_weld.h"

#include <algorithm>
#include <numeric>
#include <tuple>

namespace rayfarm {

WeldedCorners weld_corners(std::span<const CornerIndices> corners, uint64_t* comparisons) {
  const size_t count = corners.size();
  std::vector<uint32_t> order(count);
  std::iota(order.begin(), order.end(), 0u);
  uint64_t compared = 0;
  // The corner's own index breaks ties, so that each run of equal corners starts with the first
  // one in the file and the numbering below does not depend on the sort's stability.
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    ++compared;
    const CornerIndices &x = corners[a], &y = corners[b];
    return std::tie(x.v, x.t, x.n, a) < std::tie(y.v, y.t, y.n, b);
  });
  if (comparisons != nullptr) *comparisons = compared;

  // first_of[i]: the first corner equal to corner i.
  std::vector<uint32_t> first_of(count);
  for (size_t k = 0; k < count; ++k) {
    const bool starts_run = k == 0 || !(corners[order[k]] == corners[order[k - 1]]);
    first_of[order[k]] = starts_run ? order[k] : first_of[order[k - 1]];
  }
  WeldedCorners out;
  out.vertex_of.resize(count);
  for (uint32_t i = 0; i < count; ++i) {
    if (first_of[i] == i) {
      out.vertex_of[i] = static_cast<uint32_t>(out.first_corner.size());
      out.first_corner.push_back(i);
    } else {
      out.vertex_of[i] = out.vertex_of[first_of[i]];  // an earlier corner: already numbered
    }
  }
  return out;
}

}  // namespace rayfarm
