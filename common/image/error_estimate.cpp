#include "common/image/error_estimate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace rayfarm {

double variance_of_mean(Fixed sum, Fixed sum_sq, uint32_t n) {
  if (n < 2) return std::numeric_limits<double>::infinity();
  constexpr long double kScale = 1.0L / 1099511627776.0L;  // 2^-40
  const long double s = fixed_raw_long_double(sum) * kScale;
  const long double q = fixed_raw_long_double(sum_sq) * kScale;
  const long double nn = n;
  const long double spread = q - s * (s / nn);  // (n - 1) times the sample variance
  if (!(spread > 0)) return 0.0;
  return static_cast<double>(spread / (nn * (nn - 1)));
}

double ErrorEstimate::rmse() const { return std::sqrt(mse); }

namespace {

/// The median of the first `k` (1 to 8) values, by insertion sort: the value nth_element would
/// give, since the median of a set does not depend on how it is found. Pixels on a rectangle's
/// border have fewer than nine neighbours; the others go through interior_medians().
double median_of(double* v, int k) {
  for (int i = 1; i < k; ++i) {
    const double x = v[i];
    int j = i - 1;
    for (; j >= 0 && v[j] > x; --j) v[j + 1] = v[j];
    v[j + 1] = x;
  }
  return v[k / 2];
}

/// One exchange of a median network: a and b end in order.
inline void exchange(double& a, double& b) {
  const double lo = std::min(a, b), hi = std::max(a, b);
  a = lo;
  b = hi;
}

/// The medians of the full 3x3 neighbourhoods along one row of a channel's means (pixels 1 to
/// w - 2; `up` and `down` the rows above and below): a branch-free network of 19 min/max
/// exchanges, pixel by pixel with no branch, so that the compiler runs it on several at once.
void interior_medians(const double* up, const double* mid, const double* down, double* out,
                      uint32_t w) {
  for (uint32_t x = 1; x + 1 < w; ++x) {
    double v0 = up[x - 1], v1 = up[x], v2 = up[x + 1];
    double v3 = mid[x - 1], v4 = mid[x], v5 = mid[x + 1];
    double v6 = down[x - 1], v7 = down[x], v8 = down[x + 1];
    exchange(v1, v2), exchange(v4, v5), exchange(v7, v8), exchange(v0, v1), exchange(v3, v4);
    exchange(v6, v7), exchange(v1, v2), exchange(v4, v5), exchange(v7, v8), exchange(v0, v3);
    exchange(v5, v8), exchange(v4, v7), exchange(v3, v6), exchange(v1, v4), exchange(v2, v5);
    exchange(v4, v7), exchange(v2, v4), exchange(v4, v6), exchange(v2, v4);
    out[x] = v4;
  }
}

/// Per-thread scratch of an estimate, planar by channel: the master estimates a tile after each
/// merge, and these would otherwise be allocated and faulted in every time.
struct EstimateScratch {
  std::vector<double> mean, var, median;
};

}  // namespace

ErrorEstimate estimate_error(const Film& film, const TileRect& rect_in) {
  const TileRect rect =
      rect_in.pixel_count() == 0 ? TileRect{0, 0, film.width(), film.height()} : rect_in;
  ErrorEstimate e;
  e.known = true;
  e.pixels = rect.pixel_count();
  const uint32_t w = rect.width(), h = rect.height();
  const std::vector<uint32_t>& spp = film.spp();
  const auto film_index = [&](uint32_t x, uint32_t y) { return size_t{y} * film.width() + x; };
  for (uint32_t y = rect.y0; y < rect.y1 && e.known; ++y) {
    for (uint32_t x = rect.x0; x < rect.x1; ++x) {
      if (spp[film_index(x, y)] < 2) {
        e.known = false;
        break;
      }
    }
  }
  if (!e.known || e.pixels == 0) {
    e.rel_mse = e.mse = std::numeric_limits<double>::infinity();
    return e;
  }
  // Each pixel's mean and variance of the mean, converted once, channel by channel (a channel's
  // values at c * pixels + local index): the medians read each mean up to nine times, and the
  // per-value arithmetic below runs over whole rows.
  const size_t pixels = e.pixels;
  thread_local EstimateScratch scratch;
  // Each checked on its own: a resize that ran out of memory leaves the others as they were.
  for (std::vector<double>* v : {&scratch.mean, &scratch.var, &scratch.median}) {
    if (v->size() < pixels * 3) v->resize(pixels * 3);
  }
  double* const mean = scratch.mean.data();
  double* const var = scratch.var.data();
  double* const median = scratch.median.data();
  for (uint32_t y = rect.y0; y < rect.y1; ++y) {
    for (uint32_t x = rect.x0; x < rect.x1; ++x) {
      const size_t p = film_index(x, y), q = size_t{y - rect.y0} * w + (x - rect.x0);
      for (int c = 0; c < 3; ++c) {
        mean[c * pixels + q] = from_fixed(film.sum()[p * 3 + c]) / spp[p];
        var[c * pixels + q] =
            variance_of_mean(film.sum()[p * 3 + c], film.sum_sq()[p * 3 + c], spp[p]);
      }
    }
  }
  // The 3x3 neighbourhood within `rect`: a tile's estimate is a function of the tile's own
  // samples (the pass planner relies on it). A firefly is one pixel: it cannot move the median.
  // Pixels with all eight neighbours take the network row by row; those on the rectangle's
  // border gather the neighbours they have.
  for (int c = 0; c < 3; ++c) {
    const double* m = mean + c * pixels;
    double* out = median + c * pixels;
    for (uint32_t ly = 0; ly < h; ++ly) {
      const bool full_rows = ly > 0 && ly + 1 < h;
      if (full_rows) {
        interior_medians(m + (ly - 1) * size_t{w}, m + ly * size_t{w}, m + (ly + 1) * size_t{w},
                         out + ly * size_t{w}, w);
      }
      for (uint32_t lx = 0; lx < w; ++lx) {
        if (full_rows && lx > 0 && lx + 1 < w) continue;
        double v[9];
        int k = 0;
        for (uint32_t yy = ly > 0 ? ly - 1 : ly; yy <= std::min(ly + 1, h - 1); ++yy) {
          for (uint32_t xx = lx > 0 ? lx - 1 : lx; xx <= std::min(lx + 1, w - 1); ++xx) {
            v[k++] = m[size_t{yy} * w + xx];
          }
        }
        out[size_t{ly} * w + lx] = median_of(v, k);
      }
    }
  }
  // Each value's relative error, in place of its median. The value the pixel converges to: the
  // larger of its neighbourhood's median and a lower bound of its own mean, two standard errors
  // down. A firefly's mean is no larger than two of its standard errors, so its neighbours judge
  // it; a pixel that is simply brighter than its neighbours (the edge of a light) keeps its own
  // value.
  for (size_t i = 0; i < pixels * 3; ++i) {
    const double own = mean[i] - 2.0 * std::sqrt(var[i]);
    const double value = std::max(median[i], own);
    median[i] = var[i] / (value * value + kRelMseEpsilon);
  }
  // Summed in long double, pixel by pixel, channel by channel.
  long double rel = 0, mse = 0;
  for (size_t q = 0; q < pixels; ++q) {
    for (int c = 0; c < 3; ++c) {
      rel += median[c * pixels + q];
      mse += var[c * pixels + q];
    }
  }
  const long double values = 3.0L * static_cast<long double>(e.pixels);
  e.rel_mse = static_cast<double>(rel / values);
  e.mse = static_cast<double>(mse / values);
  return e;
}

TiledErrorEstimate::TiledErrorEstimate(std::vector<TileRect> tiles)
    : tiles_(std::move(tiles)), estimates_(tiles_.size()) {
  for (size_t t = 0; t < tiles_.size(); ++t) {
    estimates_[t].pixels = tiles_[t].pixel_count();
    estimates_[t].rel_mse = estimates_[t].mse = std::numeric_limits<double>::infinity();
  }
}

void TiledErrorEstimate::update(const Film& film, uint32_t tile) {
  estimates_[tile] = estimate_error(film, tiles_[tile]);
}

void TiledErrorEstimate::update_all(const Film& film) {
  for (uint32_t t = 0; t < tiles_.size(); ++t) update(film, t);
}

ErrorEstimate TiledErrorEstimate::whole() const {
  ErrorEstimate e;
  e.known = !estimates_.empty();
  long double rel = 0, mse = 0;
  for (const ErrorEstimate& t : estimates_) {
    e.pixels += t.pixels;
    e.known = e.known && t.known;
    rel += static_cast<long double>(t.rel_mse) * t.pixels;
    mse += static_cast<long double>(t.mse) * t.pixels;
  }
  if (!e.known || e.pixels == 0) {
    e.known = false;
    e.rel_mse = e.mse = std::numeric_limits<double>::infinity();
    return e;
  }
  e.rel_mse = static_cast<double>(rel / e.pixels);
  e.mse = static_cast<double>(mse / e.pixels);
  return e;
}

int TiledErrorEstimate::worst_tile() const {
  int worst = -1;
  for (size_t t = 0; t < estimates_.size(); ++t) {
    if (!estimates_[t].known) return static_cast<int>(t);  // its error is unbounded
    if (worst < 0 || estimates_[t].rel_mse > estimates_[worst].rel_mse) worst = static_cast<int>(t);
  }
  return worst;
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
