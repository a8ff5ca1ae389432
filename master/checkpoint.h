#pragma once
// Checkpoints of running jobs: everything merged so far (the film's exact sums, which units are
// merged, the planner's decisions, the error rows, the time spent), so that a master killed in
// the middle of a job resumes it where the checkpoint left it, bit for bit.
//
// A job keeps two generations, jobs/<id>/checkpoint-0.bin and checkpoint-1.bin; each write goes to
// the slot that does not hold the newest one, through a temporary file that is synced and renamed
// (and the folder synced), so a crash at any moment leaves at least one complete checkpoint. On
// load the newest valid one wins; a file that is truncated, corrupt (SHA-256 mismatch) or
// inconsistent is named with its cause and the older one is used.
//
// File layout (little-endian):
//   "RFCKPT\r\n"  magic, 8 bytes
//   u32           format version (kCheckpointVersion)
//   u64           payload size in bytes
//   payload       checkpoint.cpp: encode_payload lists the fields in order
//   32 bytes      SHA-256 of everything before it
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/image/fixed.h"
#include "common/report/error_log.h"
#include "common/schedule/pass_planner.h"
#include "master/background_writer.h"

namespace rayfarm::master {

/// Version 2 dropped what the merged map already says (samples per pixel, per-tile merged counts)
/// and the planner's always-empty pending list; version 1 files are still read.
inline constexpr uint32_t kCheckpointVersion = 2;

/// The merged state of one running job.
struct Checkpoint {
  uint64_t sequence = 0;  ///< grows by one with each checkpoint of the job
  std::string job_id;
  // The job's grid, checked against the job's settings when it is loaded.
  uint32_t width = 0, height = 0, tile_size = 0, spp = 0, pass_spp = 0;
  double elapsed_seconds = 0.0;     ///< rendering time so far (from the first unit handed out)
  std::vector<uint8_t> merged;      ///< one byte per unit, 1 when merged
  std::vector<Fixed> sum, sum_sq;   ///< the film's sums, RGB per pixel, row-major
  uint64_t nonfinite = 0, rays = 0;
  PlannerState planner;
  std::vector<ErrorRow> rows;  ///< the error record (error.csv) so far
  uint32_t rounds_recorded = 0;
  uint64_t samples_recorded = 0;
};

/// A checkpoint that cannot be used; what() is the cause (the caller adds the file).
class CheckpointError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The bytes of a checkpoint file.
std::string encode_checkpoint(const Checkpoint& checkpoint);
/// Parses a checkpoint file's bytes (this version or version 1). Throws CheckpointError:
/// truncated, checksum mismatch, unknown version, malformed payload.
Checkpoint decode_checkpoint(const std::string& bytes);

/// The file of generation slot `slot` (0 or 1) in a job's folder.
std::filesystem::path checkpoint_path(const std::filesystem::path& job_dir, int slot);
/// Reads and decodes one file. Throws CheckpointError "FILE: cause".
Checkpoint read_checkpoint(const std::filesystem::path& path);

struct LoadedCheckpoint {
  Checkpoint checkpoint;
  int slot = 0;
  std::filesystem::path file;
};
/// The newest usable checkpoint of a job's folder; nullopt when none. Each file present but
/// unusable adds "FILE: cause" to `problems`; `accept` may reject a decoded checkpoint by throwing
/// CheckpointError (e.g. it belongs to other settings), and the next one is tried.
std::optional<LoadedCheckpoint> load_newest_checkpoint(
    const std::filesystem::path& job_dir, std::vector<std::string>& problems,
    const std::function<void(const Checkpoint&)>& accept = {});
/// Removes both generations (the job is finished).
void remove_checkpoints(const std::filesystem::path& job_dir);

/// Writes checkpoints on a thread of its own, so that the broker's reactor only pays for the copy
/// of the sums. Only the newest checkpoint of a job matters: a queued one is replaced. Each write
/// goes to the slot that does not hold the job's newest checkpoint.
class CheckpointWriter {
 public:
  /// Queues `checkpoint` for the job whose folder is `job_dir`.
  void submit(const std::filesystem::path& job_dir, Checkpoint checkpoint);
  /// The job's newest checkpoint is in slot `slot` (it was loaded from there).
  void set_newest_slot(const std::string& job_id, int slot);
  /// Returns when everything queued before the call is written (or failed, which is logged).
  void flush();
  /// Drops the job's queued checkpoint and queues the deletion of both files (after a checkpoint
  /// of the job being written, if any), without waiting.
  void forget(const std::string& job_id, const std::filesystem::path& job_dir);
  /// Why the job's latest checkpoint could not be written; "" when it was (or none was tried).
  std::string failure(const std::string& job_id) const;
  /// Seconds the job's latest checkpoint took to encode and write; 0 before the first.
  double seconds(const std::string& job_id) const;

 private:
  struct Task {
    std::filesystem::path job_dir;
    Checkpoint checkpoint;
    bool remove = false;  // delete the job's checkpoints instead
  };
  mutable std::mutex mutex_;  // guards newest_slot_, failures_ and seconds_
  std::map<std::string, int> newest_slot_;
  std::map<std::string, std::string> failures_;  // job id -> why its latest checkpoint failed
  std::map<std::string, double> seconds_;        // job id -> what its latest checkpoint took
  BackgroundWriter<Task> tasks_{[this](Task& task) { write(task); }};  // last: uses the above

  void write(Task& task);
};

}  // namespace rayfarm::master
