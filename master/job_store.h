#pragma once
// The master's data dir. Every file is written to a temporary name and renamed into place, so a
// reader (or a crash) never sees half a file.
//
//   <data>/jobs/<id>/job.json    the job: settings, state, error (job_store.cpp lists the keys)
//   <data>/jobs/<id>/bundle.pb   the scene bundle (a serialized rayfarm.wire.Bundle)
//   <data>/jobs/<id>/image.exr   the current estimate, float32 RGB, rewritten as passes complete
//   <data>/jobs/<id>/image.png   its sRGB preview
//   <data>/jobs/<id>/reference.exr  the reference image the job's error is measured against
//   <data>/jobs/<id>/error.csv   error against time, one row per pass (common/report/error_log.h)
//   <data>/jobs/<id>/error.png   its log-log plot
//   <data>/jobs/<id>/checkpoint-0.bin, checkpoint-1.bin  a running job's merged state, two
//                                generations (checkpoint.h); removed when the job ends
//   <data>/jobs/<seq>/bundle.pb  a sequence's bundle, which its frames' jobs render (their
//                                folders are <data>/jobs/<seq>.<frame>/, without a bundle.pb)
//   <data>/jobs/<seq>/sequence.json  written once every frame's job.json is on disk; then holds
//                                the sequence's own state (SequenceRecord), rewritten as it
//                                changes
//   <data>/tmp/                  scratch space (scene validation), emptied at start
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/scene/scene.h"
#include "common/schedule/stop_rules.h"
#include "master/job_log.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master {

/// What a job is: fixed when it is accepted.
struct JobSpec {
  std::string id;
  std::string name;
  std::string bundle_hash;
  std::string scene_path;  ///< the scene file inside the bundle
  /// The frame of an animated scene the job renders; nullopt for a still scene. An animated
  /// scene submitted without a frame renders its first, named here.
  std::optional<int64_t> frame;
  /// The sequence the job is a frame of (its id, e.g. "j0007"; the frame's own id is
  /// "j0007.0012"); empty for a job of its own.
  std::string sequence;
  /// A frame of a list of scene files ("frame_####.json"): scene_path names the frame's own file,
  /// a still scene, and units carry no frame.
  bool frame_file = false;
  RenderSettings settings;
  FilmSize film;
  uint32_t tile_size = kDefaultTileSize;
  uint32_t pass_spp = 1;
  StopRules stop;              ///< target error and time limit, besides settings.spp
  bool has_reference = false;  ///< reference.exr is in the job's folder
  int64_t submitted_unix_ms = 0;
  /// The name of the client key that submitted the job ("" on a master without keys): only it,
  /// or an admin key, may cancel the job.
  std::string owner;
};

/// A job as stored: its spec and where it stands.
struct JobRecord {
  JobSpec spec;
  wire::JobState state = wire::JOB_QUEUED;
  std::string error;
  double elapsed_seconds = 0.0;  ///< from the first unit handed out to the end
  std::string stop_reason;       ///< once finished: stop_reason_name() of why
  // Once finished: the final image's figures.
  uint64_t units_done = 0;
  uint32_t passes_done = 0;      ///< passes every pixel has (UnitGrid::passes_within)
  uint32_t spp_min = 0;          ///< fewest samples of any pixel
  double spp_mean = 0.0;
  uint32_t tiles_converged = 0;
  double est_rel_mse = -1.0;     ///< negative: unknown
  double ref_rel_mse = -1.0;     ///< negative: no reference
  /// How the job shares the farm (Scheduler): changeable while it is queued or running.
  int32_t priority = 0;
  bool paused = false;
  /// When the job was last queued by a retry (Unix ms); 0: never, it was queued when submitted.
  int64_t queued_unix_ms = 0;
  /// When its first unit was handed out since it was last queued, and when it ended (Unix ms);
  /// 0: not yet.
  int64_t started_unix_ms = 0;
  int64_t finished_unix_ms = 0;
  /// What happened to it (job_log.h).
  JobLog log;
  /// The job's job.json could not be read: state is JOB_STATE_UNSPECIFIED, `error` says why, and
  /// only spec.id is known. Such a record is listed, never saved over.
  bool unreadable = false;
};

/// A sequence's own state (sequence.json): what is set once for all its frames.
struct SequenceRecord {
  std::string id;
  size_t frames = 0;
  double fps = 24.0;  ///< the frames a second its movie plays at
  /// The sequence's priority and pause, its frames' (a frame may still be paused alone, in its
  /// own record). `has_state` is false for a sequence stored before they were kept here: its
  /// frames' records hold them.
  bool has_state = false;
  int32_t priority = 0;
  bool paused = false;
  /// When the sequence was last cancelled (Unix ms; 0: never): a frame whose record still says
  /// queued or running and was queued before then is cancelled (a cancel ends the frames a slice
  /// at a time, and writes the records only of those that had started).
  int64_t cancelled_unix_ms = 0;
  /// Seconds of rendering, wall time, pauses left out; negative: unknown (not kept).
  double elapsed_seconds = -1.0;
};

class JobStore {
 public:
  /// Opens (creating) the data dir. Throws std::runtime_error naming the folder on failure.
  explicit JobStore(std::filesystem::path data_dir);

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path job_dir(const std::string& id) const;
  /// A new job id ("j0001", "j0002", ...), never one in use in the data dir. Thread-safe, as are
  /// make_scratch_dir and the writers of one job's files.
  std::string allocate_id();
  /// The id of frame `frame` of sequence `sequence` ("j0007.0012": four digits at least).
  static std::string frame_id(const std::string& sequence, int64_t frame);
  /// Creates the folder of a frame's job (its id from frame_id()). Throws std::runtime_error.
  void create_job_dir(const std::string& id);
  /// The folder id whose bundle.pb a job renders: its sequence's for a frame, else its own.
  static const std::string& bundle_holder(const JobSpec& spec) {
    return spec.sequence.empty() ? spec.id : spec.sequence;
  }
  /// Records that every frame of sequence `id` is stored (jobs/<id>/sequence.json, synced): a
  /// sequence without it was cut short by a crash while being accepted. Throws
  /// std::runtime_error.
  void mark_sequence_stored(const SequenceRecord& record);
  /// Rewrites sequence.json (the file alone: the folder is synced already). Throws
  /// std::runtime_error on an I/O error.
  void save_sequence(const SequenceRecord& record);
  /// Reads sequence.json; what it lacks or cannot be read keeps SequenceRecord's defaults.
  SequenceRecord load_sequence(const std::string& id) const;
  bool sequence_stored(const std::string& id) const;
  /// The frames a second of sequence `id`'s movie (24 when its sequence.json does not say).
  double sequence_fps(const std::string& id) const;
  /// A fresh empty folder under tmp/.
  std::filesystem::path make_scratch_dir();

  /// Writes job.json. Throws std::runtime_error on an I/O error.
  void save_record(const JobRecord& record);
  /// Syncs the job's folder and the jobs folder, so that files renamed into them (job.json,
  /// bundle.pb) and the folder itself survive a power cut. Throws std::runtime_error.
  void sync_job_dir(const std::string& id);
  /// Writes bundle.pb. Throws std::runtime_error on an I/O error.
  void save_bundle(const std::string& id, const wire::Bundle& bundle);
  /// Writes reference.exr (bytes already checked to be a readable EXR of the film's size).
  void save_reference(const std::string& id, const std::string& exr_bytes);
  std::filesystem::path reference_path(const std::string& id) const {
    return job_dir(id) / "reference.exr";
  }
  /// Reads bundle.pb; nullopt when missing or unreadable.
  std::optional<wire::Bundle> load_bundle(const std::string& id) const;
  /// Where the job's image goes; its preview is image.png beside it.
  std::filesystem::path image_path(const std::string& id) const {
    return job_dir(id) / "image.exr";
  }
  /// The bytes of a file of the job's folder (image.exr, error.csv, ...), nullopt when missing.
  std::optional<std::string> read_file(const std::string& id, const std::string& name) const;
  /// Every job.json, in id order. One that cannot be read (malformed, a missing key, a bad value)
  /// is logged and returned as an unreadable record (JobRecord::unreadable) naming the cause.
  /// A figure that is not finite is written as unknown (-1 or 0), and null reads back as unknown.
  std::vector<JobRecord> load_records() const;

 private:
  std::filesystem::path root_;
  std::mutex mutex_;  // guards the counters: ids and scratch folders are made on any thread
  uint64_t next_id_ = 1;
  uint64_t scratch_counter_ = 0;
};


}  // namespace rayfarm::master
