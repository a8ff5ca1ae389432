#include "common/image/error_estimate.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rayfarm {

double variance_of_mean(Fixed sum, Fixed sum_sq, uint32_t n) {
  if (n < 2) return std::numeric_limits<double>::infinity();
  constexpr long double kScale = 1.0L / 1099511627776.0L;  // 2^-40
  const long double s = static_cast<long double>(sum) * kScale;
  const long double q = static_cast<long double>(sum_sq) * kScale;
  const long double nn = n;
  const long double spread = q - s * (s / nn);  // (n - 1) times the sample variance
  if (!(spread > 0)) return 0.0;
  return static_cast<double>(spread / (nn * (nn - 1)));
}

double ErrorEstimate::rmse() const { return std::sqrt(mse); }

namespace {

double mean_at(const Film& film, size_t p, int c) {
  const uint32_t n = film.spp()[p];
  return n > 0 ? from_fixed(film.sum()[p * 3 + c]) / n : 0.0;
}

/// The median of pixel (x, y)'s channel `c` over its 3x3 neighbourhood within `rect` (pixels
/// with samples). A firefly is one pixel: it cannot move the median. Staying within `rect` keeps
/// a tile's estimate a function of the tile's own samples (convergence.h relies on it).
double median_mean(const Film& film, uint32_t x, uint32_t y, int c, const TileRect& rect) {
  double v[9];
  int k = 0;
  for (uint32_t yy = y > rect.y0 ? y - 1 : y; yy <= std::min(y + 1, rect.y1 - 1); ++yy) {
    for (uint32_t xx = x > rect.x0 ? x - 1 : x; xx <= std::min(x + 1, rect.x1 - 1); ++xx) {
      const size_t p = size_t{yy} * film.width() + xx;
      if (film.spp()[p] > 0) v[k++] = mean_at(film, p, c);
    }
  }
  std::nth_element(v, v + k / 2, v + k);
  return v[k / 2];
}

}  // namespace

ErrorEstimate estimate_error(const Film& film, const TileRect& rect_in) {
  const TileRect rect = rect_in.pixel_count() == 0 ? TileRect{0, 0, film.width(), film.height()}
                                                   : rect_in;
  ErrorEstimate e;
  e.known = true;
  long double rel = 0, mse = 0;
  for (uint32_t y = rect.y0; y < rect.y1; ++y) {
    for (uint32_t x = rect.x0; x < rect.x1; ++x) {
      const size_t p = size_t{y} * film.width() + x;
      const uint32_t n = film.spp()[p];
      ++e.pixels;
      if (n < 2) {
        e.known = false;
        continue;
      }
      for (int c = 0; c < 3; ++c) {
        const double var = variance_of_mean(film.sum()[p * 3 + c], film.sum_sq()[p * 3 + c], n);
        // The value the pixel converges to: the larger of its neighbourhood's median and a
        // lower bound of its own mean, two standard errors down. A firefly's mean is no larger
        // than two of its standard errors, so its neighbours judge it; a pixel that is simply
        // brighter than its neighbours (the edge of a light) keeps its own value.
        const double own = from_fixed(film.sum()[p * 3 + c]) / n - 2.0 * std::sqrt(var);
        const double value = std::max(median_mean(film, x, y, c, rect), own);
        rel += var / (value * value + kRelMseEpsilon);
        mse += var;
      }
    }
  }
  if (!e.known || e.pixels == 0) {
    e.rel_mse = e.mse = std::numeric_limits<double>::infinity();
    return e;
  }
  const long double values = 3.0L * static_cast<long double>(e.pixels);
  e.rel_mse = static_cast<double>(rel / values);
  e.mse = static_cast<double>(mse / values);
  return e;
}

std::vector<float> variance_rgb(const Film& film) {
  std::vector<float> out(film.sum().size());
  for (size_t p = 0; p < film.spp().size(); ++p) {
    for (int c = 0; c < 3; ++c) {
      out[p * 3 + c] = static_cast<float>(
          variance_of_mean(film.sum()[p * 3 + c], film.sum_sq()[p * 3 + c], film.spp()[p]));
    }
  }
  return out;
}

}  // namespace rayfarm
