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
  explicit ErrorTracker(std::optional<Image> reference = std::nullopt)
      : reference_(std::move(reference)) {}

  /// Appends the row for `film` `seconds` after the render started, and returns it.
  const ErrorRow& record(const Film& film, double seconds);
  const std::vector<ErrorRow>& rows() const { return rows_; }
  bool has_reference() const { return reference_.has_value(); }
  /// The estimate behind the last row.
  const ErrorEstimate& last_estimate() const { return last_; }

 private:
  std::optional<Image> reference_;
  std::vector<ErrorRow> rows_;
  ErrorEstimate last_;
};

}  // namespace rayfarm
