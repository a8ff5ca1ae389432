#pragma once
// Builds the error-against-time record (error_log.h) of a render as it goes: at each report the
// estimated error from the film's own samples (error_estimate.h) and, when a reference image is
// given, the error measured against it (metrics.h). `rayfarm render` and the master both use it.
#include <filesystem>
#include <optional>
#include <vector>

#include "common/image/error_estimate.h"
#include "common/image/exr.h"
#include "common/image/film.h"
#include "common/report/error_log.h"

namespace rayfarm {

/// Reads a reference image for a film of `film` size. Throws ImageError naming the file and, when
/// they differ, both sizes.
Image load_reference(const std::filesystem::path& path, FilmSize film);
/// Checks that `reference` fits a film of `film` size; throws ImageError naming `source`.
void check_reference(const Image& reference, FilmSize film, const std::string& source);

class ErrorTracker {
 public:
  /// `tiles` cut the film for the estimate (TiledErrorEstimate): the render's tiles.
  explicit ErrorTracker(std::vector<TileRect> tiles, std::optional<Image> reference = std::nullopt)
      : estimate_(std::move(tiles)), reference_(std::move(reference)) {}

  /// Tile `tile` of `film` changed: its estimate is recomputed now (O(tile)).
  void update_tile(const Film& film, uint32_t tile) { estimate_.update(film, tile); }
  /// Every tile of `film` changed (a film restored from a checkpoint).
  void estimate_all(const Film& film) { estimate_.update_all(film); }
  /// The row for `film` `seconds` after the render started (the caller keeps the record). Every
  /// tile's estimate is recomputed first unless `tiles_current` says update_tile saw every change.
  ErrorRow record(const Film& film, double seconds, bool tiles_current = false);
  bool has_reference() const { return reference_.has_value(); }
  /// The estimates behind the last row, tile by tile.
  const TiledErrorEstimate& estimate() const { return estimate_; }

 private:
  TiledErrorEstimate estimate_;
  std::optional<Image> reference_;
};

}  // namespace rayfarm
