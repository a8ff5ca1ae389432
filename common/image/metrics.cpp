#include "common/image/metrics.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

namespace rayfarm {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

uint32_t bits_of(float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof(bits));
  return bits;
}

std::string size_of(const Image& image) {
  return std::to_string(image.width) + "x" + std::to_string(image.height);
}

/// Sums over one row, added to the totals row by row to keep the double sums accurate.
struct RowSums {
  double sq = 0.0, rel = 0.0, abs = 0.0;
};

}  // namespace

ImageDiff compare_images(const Image& test, const Image& reference) {
  if (test.width != reference.width || test.height != reference.height) {
    throw ImageError("image sizes differ: test is " + size_of(test) + ", reference is " +
                     size_of(reference));
  }
  const size_t row = size_t{test.width} * 3;
  const size_t n = row * test.height;
  if (test.rgb.size() != n || reference.rgb.size() != n) {
    throw ImageError("malformed image: " + size_of(test) + " needs " + std::to_string(n) +
                     " RGB values, test has " + std::to_string(test.rgb.size()) +
                     ", reference has " + std::to_string(reference.rgb.size()));
  }

  ImageDiff diff;
  diff.values = n;
  double sum_sq = 0.0, sum_rel = 0.0, sum_abs = 0.0;
  for (size_t begin = 0; begin < n; begin += row) {
    RowSums sums;
    for (size_t i = begin; i < begin + row; ++i) {
      const float a = test.rgb[i], b = reference.rgb[i];
      const bool nan = std::isnan(a) || std::isnan(b);
      if (nan) ++diff.nan_values;
      if (bits_of(a) == bits_of(b) && !nan) continue;  // -0 vs +0 differs in bits, by 0.0
      ++diff.differing;
      // Infinite when a NaN is involved or infinities differ (inf - inf would give NaN).
      double d = std::fabs(static_cast<double>(a) - static_cast<double>(b));
      if (std::isnan(d)) d = kInfinity;
      const double bb = static_cast<double>(b) * b;
      sums.sq += d * d;
      sums.rel += std::isinf(d) ? kInfinity : d * d / (bb + 1e-2);
      sums.abs += d;
      diff.max_abs = std::max(diff.max_abs, d);
    }
    sum_sq += sums.sq;
    sum_rel += sums.rel;
    sum_abs += sums.abs;
  }

  diff.identical = diff.differing == 0;
  if (n > 0) {
    const auto count = static_cast<double>(n);
    diff.rmse = std::sqrt(sum_sq / count);
    diff.rel_mse = sum_rel / count;
    diff.mae = sum_abs / count;
  }
  return diff;
}

}  // namespace rayfarm
