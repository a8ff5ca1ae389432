#pragma once
// The error of a film's estimate, from its own samples (no reference needed). Every sample of a
// pixel is an independent estimate of the pixel's value (its random numbers depend only on
// seed, pixel and sample index), so the spread of the samples gives the variance of their mean.
// The film keeps the sums of samples and of squared samples as exact fixed-point numbers
// (fixed.h): accumulation has no rounding at all and does not depend on the order of merging,
// which a running Welford update in double could not promise. The one rounding is the final
// subtraction, done in long double (docs/error.md).
#include <cstdint>
#include <vector>

#include "common/image/film.h"

namespace rayfarm {

/// The epsilon of relative MSE, mean((a - b)^2 / (b^2 + epsilon)): the same as metrics.h, so an
/// estimate and a measurement against a reference are the same quantity.
inline constexpr double kRelMseEpsilon = 1e-2;

/// Variance of the mean of `n` samples whose sum is `sum` and sum of squares `sum_sq`:
/// (sum_sq - sum^2 / n) / (n (n - 1)), never negative. +inf when n < 2 (unknown).
double variance_of_mean(Fixed sum, Fixed sum_sq, uint32_t n);

/// Error of the estimate over a set of pixels. Relative MSE divides each pixel's variance by the
/// square of the value it converges to; with no reference, that value is taken as the larger of
/// the median of the pixel's 3x3 neighbourhood and its own mean less two standard errors.
/// Dividing by the pixel's own mean would hide fireflies (a pixel with one huge sample has a
/// huge mean too, and its relative error would look small exactly where it is largest);
/// dividing by the median alone would inflate the error of pixels that are simply brighter than
/// their neighbours, such as the edge of a light. docs/error.md has the measurements.
struct ErrorEstimate {
  double rel_mse = 0.0;   ///< mean over pixels and channels of var / (value^2 + kRelMseEpsilon)
  double mse = 0.0;       ///< mean over pixels and channels of var (the expected squared error)
  uint64_t pixels = 0;    ///< pixels counted
  bool known = false;     ///< false while some pixel has fewer than 2 samples (error is +inf)
  double rmse() const;
};

/// The estimated error of the pixels in `rect` (the whole film when rect is empty), from the
/// samples inside `rect` only.
ErrorEstimate estimate_error(const Film& film, const TileRect& rect = {});

/// The estimate of a film cut into tiles, kept tile by tile: a tile's figure is recomputed when
/// the tile changes (update, O(tile)), and the whole image's is the pixel-weighted mean of the
/// tiles' (O(tiles)). Medians stay within tiles, as in estimate_error(film, tile). The master
/// updates a tile as each result merges, so that the figures it logs after a pass cost nothing
/// in proportion to the image; `rayfarm render` updates all tiles at each report.
class TiledErrorEstimate {
 public:
  explicit TiledErrorEstimate(std::vector<TileRect> tiles);
  void update(const Film& film, uint32_t tile);
  void update_all(const Film& film);
  const std::vector<TileRect>& tiles() const { return tiles_; }
  const ErrorEstimate& tile(uint32_t t) const { return estimates_[t]; }
  /// The whole image: unknown while some tile is.
  ErrorEstimate whole() const;
  /// The tile with the largest relative MSE: the first one not known yet (its error is +inf),
  /// else the largest; -1 when there are no tiles.
  int worst_tile() const;

 private:
  std::vector<TileRect> tiles_;
  std::vector<ErrorEstimate> estimates_;
};

/// Per-pixel variance of the mean, interleaved RGB like Film::mean_rgb(); +inf where a pixel has
/// fewer than 2 samples. Written beside the image as the EXR layer "variance".
std::vector<float> variance_rgb(const Film& film);

}  // namespace rayfarm
