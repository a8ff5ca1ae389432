#pragma once
// Error metrics between two images of the same size.
#include <cstdint>

#include "common/image/exr.h"

namespace rayfarm {

struct ImageDiff {
  double rmse = 0.0;        ///< sqrt(mean((a-b)^2)) over pixels and channels
  double rel_mse = 0.0;     ///< mean((a-b)^2 / (b^2 + 1e-2)), b the reference
  double mae = 0.0;         ///< mean |a-b|
  double max_abs = 0.0;     ///< max |a-b|
  uint64_t differing = 0;   ///< channel values whose bits differ
  bool identical = false;   ///< every float equal bit for bit (and same size)
};

/// Compares `test` to `reference` (RGB only). Throws ImageError when sizes differ.
ImageDiff compare_images(const Image& test, const Image& reference);

}  // namespace rayfarm
