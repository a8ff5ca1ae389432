#pragma once
// Limits on what a peer can make the master do, checked before a submission is unpacked or its
// scene loaded: the messages a socket takes, the bundle's size, the image's pixels and samples per
// pixel, and the jobs waiting. Each check is a pure function that returns the refusal, naming the
// limit, the value and the master option that raises it, or nothing when the value is within.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "proto/rayfarm.pb.h"

namespace rayfarm::master {

struct Limits {
  /// Largest message a master socket accepts (ZMQ_MAXMSGSIZE); a peer sending more is
  /// disconnected by ZeroMQ before the master sees it. --max-message-mb
  int64_t max_message_bytes = int64_t{1} << 30;
  /// Largest scene bundle (the sum of its files' sizes). --max-bundle-mb
  uint64_t max_bundle_bytes = uint64_t{256} << 20;
  /// Most files in a scene bundle (each is a file the master writes when it checks the scene).
  /// --max-bundle-files
  uint64_t max_bundle_files = 4096;
  /// Most pixels of a job's image (width x height). --max-image-pixels
  uint64_t max_image_pixels = uint64_t{1} << 25;  // 33.5 Mpx: 8K UHD (7680x4320) fits
  /// Most samples per pixel of a job. --max-spp
  uint32_t max_spp = 1u << 16;
  /// Most jobs queued or running at once. --max-queued-jobs
  size_t max_queued_jobs = 100;
};

/// What a submission asks of the master, as far as the limits care.
struct SubmissionFigures {
  uint64_t bundle_bytes = 0;
  uint64_t bundle_files = 0;
  /// From the scene file's "film" and "render" blocks, with the job's overrides; unset when the
  /// scene does not say (the master's scene parser then rejects it with its own message).
  std::optional<uint64_t> width, height;
  std::optional<uint64_t> spp;
  uint64_t tile_size = 64;  ///< the override, or the default tile of 64 pixels
};

/// The bundle's size and file count only: cheap, no parsing (for the reactor thread).
SubmissionFigures bundle_figures(const wire::SubmitJob& request);
/// Reads the figures of `request`: the bundle's size, and the film size and spp from the scene
/// file's JSON (only the "film" and "render" blocks are looked at; the whole scene is loaded
/// later, once the limits pass).
SubmissionFigures figures_of(const wire::SubmitJob& request);

/// Refusal when `jobs_waiting` (queued or running) have reached the limit.
std::optional<std::string> check_queue(size_t jobs_waiting, const Limits& limits);
/// Refusal for a bundle, an image, an spp or a unit result over the limits.
std::optional<std::string> check_figures(const SubmissionFigures& figures, const Limits& limits);
/// Both checks: the first refusal, or nothing when `request` may go on to the scene parser.
std::optional<std::string> check_submission(const wire::SubmitJob& request, size_t jobs_waiting,
                                            const Limits& limits);

/// Bytes a unit result of a w x h tile takes on the wire (the sums and squared sums, 16 bytes
/// per value and channel), for comparing with the message size limit.
uint64_t unit_result_bytes(uint64_t tile_width, uint64_t tile_height);

}  // namespace rayfarm::master
