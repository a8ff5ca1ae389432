#pragma once
// Limits on what a peer can make the master do: the messages a socket takes, the bundle's size
// (checked before a submission is unpacked), the image's pixels and samples per pixel (checked by
// the scene parser before it loads any mesh, through scene_check()), and the jobs waiting. Each
// check is a pure function that returns the refusal, naming the limit, the value and the master
// option that raises it, or nothing when the value is within. The defaults are in common/limits.h.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "common/limits.h"
#include "common/scene/parser.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master {

struct Limits {
  /// Largest message a master socket accepts (ZMQ_MAXMSGSIZE); a peer sending more is
  /// disconnected by ZeroMQ before the master sees it. --max-message-mb
  int64_t max_message_bytes = kDefaultMaxMessageBytes;
  /// Largest scene bundle (the sum of its files' sizes). --max-bundle-mb
  uint64_t max_bundle_bytes = kDefaultMaxBundleBytes;
  /// Most files in a scene bundle (each is a file the master writes when it checks the scene).
  /// --max-bundle-files
  uint64_t max_bundle_files = kDefaultMaxBundleFiles;
  /// Most pixels of a job's image (width x height). --max-image-pixels
  uint64_t max_image_pixels = kDefaultMaxImagePixels;
  /// Most samples per pixel of a job. --max-spp
  uint32_t max_spp = kDefaultMaxJobSpp;
  /// Most jobs queued or running at once. --max-queued-jobs
  size_t max_queued_jobs = kDefaultMaxQueuedJobs;
};

/// What a submission asks of the master, as far as the limits care.
struct SubmissionFigures {
  uint64_t bundle_bytes = 0;
  uint64_t bundle_files = 0;
  /// The scene's film and spp with the job's overrides; unset before the scene is read.
  std::optional<uint64_t> width, height;
  std::optional<uint64_t> spp;
  uint64_t tile_size = kDefaultTileSize;  ///< the override, or the default tile
};

/// The bundle's size and file count only: cheap, no parsing (for the reactor thread).
SubmissionFigures bundle_figures(const wire::SubmitJob& request);
/// The figures of `request` whose scene has `film` and `render` (what the parser read): the
/// bundle's size, and the film size, spp and tile size with the job's overrides.
SubmissionFigures figures_of(const wire::SubmitJob& request, const FilmSize& film,
                             const RenderSettings& render);
/// The check the scene parser runs on the scene of `request` once it has read "film" and
/// "render", before any mesh: check_figures() of figures_of(). `request` must outlive it.
SceneCheck scene_check(const wire::SubmitJob& request, const Limits& limits);

/// Refusal when `jobs_waiting` (queued or running) have reached the limit.
/// A submission of `frames` jobs (a sequence's frames, 1 for a single job) when `jobs_waiting`
/// are queued or running: nullopt when the queue has room for all of them, else why not.
std::optional<std::string> check_queue(size_t jobs_waiting, const Limits& limits,
                                       uint64_t frames = 1);
/// Refusal for a bundle, an image, an spp or a unit result over the limits.
std::optional<std::string> check_figures(const SubmissionFigures& figures, const Limits& limits);

/// Most bytes a unit result of a w x h tile can take on the wire (the sums and squared sums, up
/// to kMaxFixedWireBytes per value and channel), for comparing with the message size limit.
uint64_t unit_result_bytes(uint64_t tile_width, uint64_t tile_height);

}  // namespace rayfarm::master
