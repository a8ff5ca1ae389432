#include "common/report/error_tracker.h"

#include <numeric>

#include "common/image/metrics.h"

namespace rayfarm {

void check_reference(const Image& reference, FilmSize film, const std::string& source) {
  if (reference.width != film.width || reference.height != film.height) {
    throw ImageError(source + ": the reference is " + std::to_string(reference.width) + "x" +
                     std::to_string(reference.height) + ", the image is " +
                     std::to_string(film.width) + "x" + std::to_string(film.height));
  }
}

Image load_reference(const std::filesystem::path& path, FilmSize film) {
  Image reference = read_exr(path, ExrExpect{film.width, film.height, /*rgb_only=*/true});
  check_reference(reference, film, path.string());
  reference.extra.clear();
  return reference;
}

ErrorRow ErrorTracker::record(const Film& film, double seconds, bool tiles_current) {
  if (!tiles_current) estimate_.update_all(film);
  ErrorRow row;
  const uint64_t samples = std::accumulate(film.spp().begin(), film.spp().end(), uint64_t{0});
  const double pixels = double(film.width()) * film.height();
  row.time_s = seconds;
  row.spp = pixels > 0 ? static_cast<double>(samples) / pixels : 0.0;
  row.samples_per_s = seconds > 0 ? static_cast<double>(samples) / seconds : 0.0;
  const ErrorEstimate whole = estimate_.whole();
  row.est_rel_mse = whole.rel_mse;
  row.est_rmse = whole.rmse();
  if (reference_) {
    Image image;
    image.width = film.width();
    image.height = film.height();
    image.rgb = film.mean_rgb();
    const ImageDiff diff = compare_images(image, *reference_);
    row.ref_rel_mse = diff.rel_mse;
    row.ref_rmse = diff.rmse;
    row.ref_mae = diff.mae;
    row.ref_max = diff.max_abs;
  }
  return row;
}

}  // namespace rayfarm
