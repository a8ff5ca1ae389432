#include "master/peer_limits.h"

#include <algorithm>

#include <fmt/format.h>

#include "common/protocol/convert.h"
#include "common/util/text.h"

namespace rayfarm::master {
namespace {

/// Fields and framing of a UnitResult besides its sums.
constexpr uint64_t kResultOverheadBytes = 4096;

}  // namespace

uint64_t unit_result_bytes(uint64_t tile_width, uint64_t tile_height) {
  // Packed sums are usually 6 to 8 bytes a value; a peer may need up to the most one can take.
  return 2 * tile_width * tile_height * 3 * protocol::kMaxFixedWireBytes + kResultOverheadBytes;
}

SubmissionFigures bundle_figures(const wire::SubmitJob& request) {
  SubmissionFigures f;
  for (const auto& file : request.bundle().files()) {
    f.bundle_bytes += file.data().size();
    ++f.bundle_files;
  }
  return f;
}

SubmissionFigures figures_of(const wire::SubmitJob& request, const FilmSize& film,
                             const RenderSettings& render) {
  SubmissionFigures f = bundle_figures(request);
  const wire::JobOverrides& o = request.overrides();
  if (o.tile_size() != 0) f.tile_size = o.tile_size();
  f.spp = o.has_spp() ? o.spp() : render.spp;
  f.width = film.width;
  f.height = film.height;
  if (o.width() != 0 && o.height() != 0) {  // the job's film replaces the scene's
    f.width = o.width();
    f.height = o.height();
  }
  return f;
}

SceneCheck scene_check(const wire::SubmitJob& request, const Limits& limits) {
  return [&request, limits](const FilmSize& film, const RenderSettings& render) {
    return check_figures(figures_of(request, film, render), limits);
  };
}

std::optional<std::string> check_queue(size_t jobs_waiting, const Limits& limits, uint64_t frames) {
  if (frames > 1 && frames > limits.max_queued_jobs) {
    return fmt::format(
        "a sequence of {} frames is more than the master queues at once (--max-queued-jobs {}, "
        "each frame a job); submit it in parts",
        frames, limits.max_queued_jobs);
  }
  if (jobs_waiting + std::max<uint64_t>(frames, 1) <= limits.max_queued_jobs) return std::nullopt;
  return fmt::format(
      "the master's queue is full: {} jobs are queued or running, the limit is {} "
      "(--max-queued-jobs); submit again when some have finished",
      jobs_waiting, limits.max_queued_jobs);
}

std::optional<std::string> check_figures(const SubmissionFigures& f, const Limits& limits) {
  if (f.bundle_bytes > limits.max_bundle_bytes) {
    return fmt::format(
        "the scene bundle is {} ({} bytes), over the master's limit of {} (--max-bundle-mb)",
        mib(f.bundle_bytes), f.bundle_bytes, mib(limits.max_bundle_bytes));
  }
  if (f.bundle_files > limits.max_bundle_files) {
    return fmt::format(
        "the scene bundle has {} files, over the master's limit of {} files (--max-bundle-files)",
        f.bundle_files, limits.max_bundle_files);
  }
  if (f.width && f.height) {
    const double pixels = static_cast<double>(*f.width) * static_cast<double>(*f.height);
    if (pixels > static_cast<double>(limits.max_image_pixels)) {
      return fmt::format(
          "the image is {}x{} = {:.0f} pixels, over the master's limit of {} pixels "
          "(--max-image-pixels)",
          *f.width, *f.height, pixels, limits.max_image_pixels);
    }
    const uint64_t tile_w = std::min(f.tile_size, *f.width);
    const uint64_t tile_h = std::min(f.tile_size, *f.height);
    const uint64_t result = unit_result_bytes(tile_w, tile_h);
    if (result > static_cast<uint64_t>(limits.max_message_bytes)) {
      return fmt::format(
          "a tile of {}x{} pixels makes results of {}, over the master's message limit of {} "
          "(--max-message-mb); use smaller tiles (--tile)",
          tile_w, tile_h, mib(result), mib(static_cast<uint64_t>(limits.max_message_bytes)));
    }
  }
  if (f.spp && *f.spp > limits.max_spp) {
    return fmt::format("{} samples per pixel is over the master's limit of {} spp (--max-spp)",
                       *f.spp, limits.max_spp);
  }
  return std::nullopt;
}

}  // namespace rayfarm::master
