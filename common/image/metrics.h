#pragma once
// Error metrics between two images of the same size.
#include <cstdint>

#include "common/image/exr.h"

namespace rayfarm {

/// Differences over every RGB value, accumulated in double. Values with equal bits differ by 0
/// (so equal infinities agree). A NaN in either image, or infinities that differ, count as an
/// infinite difference: the metrics below are then +inf, never a NaN or a silently finite lie.
struct ImageDiff {
  double rmse = 0.0;        ///< sqrt(mean((a-b)^2)) over pixels and channels
  double rel_mse = 0.0;     ///< mean((a-b)^2 / (b^2 + 1e-2)), b the reference
  double mae = 0.0;         ///< mean |a-b|
  double max_abs = 0.0;     ///< max |a-b|
  uint64_t differing = 0;   ///< channel values whose bits differ, or that are NaN in either image
  uint64_t nan_values = 0;  ///< channel values that are NaN in either image
  uint64_t values = 0;      ///< channel values compared: 3 * width * height
  bool identical = false;   ///< differing == 0: every float equal bit for bit, and no NaN
};

/// Compares `test` to `reference` (RGB only). Throws ImageError when sizes differ.
ImageDiff compare_images(const Image& test, const Image& reference);

}  // namespace rayfarm
