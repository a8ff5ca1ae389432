#pragma once
// The master's jobs, without sockets: accepting a job (the scene is validated first), handing out
// its units through the Scheduler, merging results through a Merger per job, writing the
// progressive image and the job's record through the JobStore, and answering status queries.
// The broker (broker.h) calls it from its one thread; nothing here is thread-safe.
//
// One facade, one file per concept: job_admission.cpp (what submit checks), job_recovery.cpp
// (checkpoints, and resuming from them), job_status.cpp (what status and list report),
// job_finish.cpp (how a job ends, on disk), job_units.cpp (leases, one unit or a run, and
// merging their results) and job_manager.cpp (the lifecycle between: rounds, failures, cancel,
// retry). A running job's parts are one ActiveJob (active_job.h).
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/scene/parser.h"
#include "master/active_job.h"
#include "master/change_budget.h"
#include "master/checkpoint.h"
#include "master/image_writer.h"
#include "master/job_store.h"
#include "master/log_budget.h"
#include "master/merger.h"
#include "master/scheduler.h"
#include "master/sequence_previews.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master {

/// A job that cannot be accepted; what() is the cause for the client (e.g. the parser's message).
class JobRejected : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct JobManagerOptions {
  /// While results arrive, the image is rewritten at least this often, and at a completed round
  /// of passes if none was written within it (the first round's always).
  std::chrono::milliseconds image_interval{3000};
  /// A unit that fails on this many different workers fails its job (a failure is a UnitFailed
  /// or a result rejected as malformed).
  int max_unit_failures = 3;
  /// How workers are named in logs; by default the hex of their id.
  std::function<std::string(const WorkerId&)> worker_name;
  /// While results arrive, a running job is checkpointed at least this often, and at a completed
  /// round of passes if none was written within it; 0 = at every round (and at shutdown) only.
  std::chrono::milliseconds checkpoint_interval{2000};
  /// A worker that fails this many times on a job is given no more of its units.
  int max_worker_failures = 3;
  /// When a slow unit is leased a second time.
  StragglerPolicy stragglers;
  /// How many of a tile's passes one lease covers (scheduler.h, "Runs"); the default, one.
  RunPolicy runs;
  /// The most share of one core that a running job's progressive images may take, and apart
  /// its checkpoints: their intervals stretch to (cost of the latest one) / write_share when
  /// that is longer (a large image). 0: the intervals as given.
  double write_share = 0.02;
  /// Who is connected now, as failures count them: each worker's key, or the worker itself
  /// without keys. A job that every one of them has been blocked from for `blocked_grace` fails
  /// (it could never finish; a worker that joins meanwhile saves it). Unset: not checked.
  std::function<std::vector<std::string>()> connected_workers;
  std::chrono::milliseconds blocked_grace{60000};
  /// The ffmpeg program that makes a finished sequence's movie (a path or a name looked up in
  /// PATH); "" makes none.
  std::string ffmpeg = "ffmpeg";
};

class JobManager {
 public:
  using Clock = std::chrono::steady_clock;

  JobManager(JobStore& store, JobManagerOptions options = {});

  /// Loads the jobs of the data dir: finished ones as they were, unfinished ones from their newest
  /// usable checkpoint (a corrupt or truncated one is logged and the older one used), or from
  /// the start when they have none. Returns how many were resumed or restarted.
  size_t recover();
  /// Checkpoints every running job (queued ones have nothing to keep) and waits until the
  /// checkpoints and images are on disk (the master is stopping). Returns how many jobs were
  /// checkpointed.
  size_t shutdown();
  /// Returns once every checkpoint queued so far is on disk (tests, benchmarks).
  void wait_for_checkpoints() { checkpoints_.flush(); }
  /// Waits until every image handed to the writer is on disk (tests).
  void wait_for_images() { writer_.flush(); }

  /// A submission checked and stored, not yet scheduled.
  struct PreparedJob {
    JobSpec spec;
    std::optional<Image> reference;  ///< read once, so that admitting it reads no file
    std::vector<std::string> warnings;
    size_t bundle_files = 0;
    uint64_t bundle_bytes = 0;
    int32_t priority = 0;  ///< as submitted (checked) and stored
    bool paused = false;
    /// A sequence: the spec of each frame's job (spec is then the sequence's: its id, no frame).
    std::vector<JobSpec> frames;
  };
  /// Validates a submission for `owner` (the submitting client key's name) and stores it in the
  /// data dir: the slow part of accepting a job (unpacking, loading the scene, reading the
  /// reference, writing and syncing files). Touches nothing but the store: safe on another thread
  /// than the rest. `check` (the master's limits, scene_check() in peer_limits.h) runs once the scene's
  /// film and render settings are read, before any mesh is loaded. Throws JobRejected naming the
  /// cause.
  PreparedJob prepare(const wire::SubmitJob& request, const std::string& owner,
                      const SceneCheck& check = {}) const;
  /// Schedules a prepared job (a sequence: every frame's job); returns its id.
  std::string admit(PreparedJob prepared);
  /// prepare() then admit(): validates and accepts a job; returns its id. Throws JobRejected.
  std::string submit(const wire::SubmitJob& request, const std::string& owner = {});
  /// The owner of a job; nullptr when the job is unknown.
  const std::string* owner_of(const std::string& id) const;

  /// The next unit for `worker`, leased to it; nullopt when no job has pending units. It may
  /// cover a run of its tile's passes (options' runs): its samples then span them, and so must
  /// the result's. When nothing is pending, a straggler (a lease running much longer per unit
  /// than its job's median) is leased to `worker` a second time, every unit of it. `key` is the
  /// name of the key the worker connected with (empty without CURVE): failures are counted, and
  /// blocks applied, per key, so that one key cannot pose as several workers by opening several
  /// connections.
  std::optional<wire::WorkUnit> next_unit(const WorkerId& worker, const std::string& key = {});
  /// Some unit could be handed out: pending, or a straggler to lease again.
  bool has_pending() const {
    return scheduler_.has_pending() || scheduler_.has_straggler(options_.stragglers);
  }

  /// Merges a result from `worker`, which must hold the unit's lease or have held it (a late
  /// result from a worker that was declared lost still counts when the unit is not merged yet).
  /// A result whose samples span a run of its tile's passes merges every unit of the run, each of
  /// which must have been leased to `worker`; when some of them were merged before, it is
  /// dropped as a duplicate. A result answers its whole lease: units of it the result leaves
  /// out go back to the queue.
  /// A result for a unit never leased to `worker` is kUnleased: dropped, and counted against
  /// nobody. A leased result whose sums are malformed or implausible is kRejected and counts as
  /// a failure of `key`.
  MergeOutcome on_result(const WorkerId& worker, const wire::UnitResult& result,
                         const std::string& key = {});
  /// A worker could not render a unit it holds: requeue it; block the worker's key from the job
  /// after max_worker_failures, fail the job when the unit failed under max_unit_failures
  /// different keys. A failure of a unit `worker` does not hold is ignored (false).
  bool on_unit_failed(const WorkerId& worker, const wire::UnitFailed& failed,
                      const std::string& key = {});
  /// Takes back the leases of a worker that is lost, gone or disabled (`why`, for the jobs'
  /// logs); returns how many were requeued.
  size_t release_worker(const WorkerId& worker, const std::string& why = "its worker is gone");

  /// Cancels a job; the state afterwards, or nullopt when the job is unknown. A sequence is
  /// cancelled at once (none of its frames gets a unit again, and the reply is CANCELLED), and
  /// its frames are ended by tick(), kCancelSlice at a time.
  /// "key 'alice'" for client key `by`, or "a client" without keys: who asked, in logs.
  static std::string requester(const std::string& by);
  /// `by` names who asked, for the job's log ("key 'alice'"; "" : a client).
  std::optional<wire::JobState> cancel(const std::string& id, const std::string& by = {});
  /// Changes how a queued or running job shares the farm: its priority (kMinPriority to
  /// kMaxPriority) and whether it is paused (no new units; those out finish and count; its clock
  /// stops). Saved in its record, so that a restart keeps it. Returns the record afterwards;
  /// nullptr when the job is unknown. Throws JobRejected naming the cause: a finished or
  /// unreadable job, a priority out of range.
  const JobRecord* change(const std::string& id, std::optional<int32_t> priority,
                          std::optional<bool> paused, const std::string& by = {});
  /// Takes one state-changing request (pause, resume, priority, cancel, retry, rm) of client key
  /// `key` out of its budget (ChangeBudget); past it, the refusal to send, naming the limit.
  std::optional<std::string> take_change(const std::string& key,
                                         Clock::time_point now = Clock::now()) {
    if (change_budget_.take(key, now)) return std::nullopt;
    return ChangeBudget::refusal();
  }
  /// The frames of a sequence ending in one tick() while it is cancelled, at most.
  static constexpr size_t kCancelSlice = 256;
  /// Of those, the frames that had started (each writes its image and record), at most.
  static constexpr size_t kCancelStartedSlice = 8;
  /// Jobs that sequence operations and tick() have visited one by one, since the start: the
  /// work they cost, which stays bounded whatever a sequence's length (tests).
  uint64_t jobs_visited() const { return jobs_visited_; }
  /// Removes a finished (done, failed, cancelled) or unreadable job and its folder. Throws
  /// JobRejected naming the cause: an unknown job, or one still queued or running.
  void remove(const std::string& id);
  /// Runs a failed or cancelled job again from its first sample, under the same id (its image
  /// and error record start over). Returns the state afterwards (queued). Throws JobRejected
  /// naming the cause: an unknown job, one that is done, queued or running, or unreadable.
  wire::JobState retry(const std::string& id, const std::string& by = {});
  /// How many jobs retry(id) would queue again: the failed or cancelled frames of a sequence, 1
  /// for a job of its own (0 when unknown).
  uint64_t retry_count(const std::string& id) const;
  /// The units `worker` holds now, as "JOB/UNIT".
  std::vector<std::string> units_of(const WorkerId& worker) const;
  /// Status of one job; nullopt when unknown. `workers_total` is the master's worker count.
  std::optional<wire::JobStatus> status(const std::string& id, uint32_t workers_total) const;
  /// A job's units, who rendered them, and its log (job_detail.cpp); nullopt when unknown. A
  /// sequence's has its status (with its frames) only.
  std::optional<wire::JobDetail> detail(const std::string& id, uint32_t workers_total) const;
  /// Status of every job, in id order.
  std::vector<wire::JobStatus> list(uint32_t workers_total) const;
  /// The job's current image; throws JobRejected when unknown or nothing is written yet. Of a
  /// sequence: with `movie` its MP4, with `sheet` its contact sheet as `png`; with neither,
  /// JobRejected (it has no image of its own).
  wire::ImageData image(const std::string& id, bool movie = false, bool sheet = false) const;
  /// Returns once every sequence preview queued so far is made (tests).
  void wait_for_previews() { previews_.flush(); }
  /// The bundle with this hash, from the store; nullopt when no job has it.
  std::optional<wire::Bundle> bundle(const std::string& hash) const;

  /// Writes the images that are due (results merged since the last write, interval passed), and
  /// ends the jobs whose time limit has passed.
  void tick();
  /// Jobs queued or running.
  size_t active_jobs() const;
  /// A message for clients: the data dir's path replaced by "<data dir>".
  std::string for_clients(const std::string& text) const;

 private:
  struct Job {
    JobRecord record;
    std::unique_ptr<ActiveJob> active;  // exactly while queued or running
    uint64_t checkpoint_sequence = 0;   // of its newest checkpoint (they outlive a retry's start)
    // Storage: `storage_error` says why the job's image, checkpoint or record cannot be written
    // now ("" when all is well); it is tried again at storage_retry.
    bool record_unsaved = false;  // the job's record could not be saved: retried
    uint64_t log_saved = 0;       // record.log.version when the record was last saved
    std::string storage_error;
    Clock::time_point storage_retry;
    std::chrono::milliseconds storage_backoff{0};
  };

  /// A sequence: its frames, and what is set once for all of them (docs/farm.md, "Frame
  /// sequences"): its priority, its pause, its cancellation, its clock.
  struct Sequence {
    std::vector<std::string> frames;  // its frames' jobs, in frame order
    int32_t priority = 0;
    bool paused = false;
    bool cancelled = false;  // a cancel is ending its frames, a slice per tick()
    size_t cancel_next = 0;  // while cancelled: the frames before it are ended
    int64_t cancelled_unix_ms = 0;  // its latest cancel (SequenceRecord)
    int64_t queued_unix_ms = 0;     // the latest time a frame of it was queued
    size_t active = 0;       // frames queued or running
    std::set<std::string> paused_alone;  // frames paused on their own (resumed with it)
    // The sequence's clock: wall time while it renders, pauses left out.
    double elapsed_before = 0.0;  // seconds up to running_since
    std::optional<Clock::time_point> running_since;
    JobRecord reply;        // what change() returns of it
    bool retrying = false;  // retry_sequence() is queueing its frames again
    double elapsed(Clock::time_point now) const {
      return elapsed_before +
             (running_since ? std::chrono::duration<double>(now - *running_since).count() : 0.0);
    }
  };

  JobStore& store_;
  JobManagerOptions options_;
  LogBudget log_budget_;
  ImageWriter writer_;
  CheckpointWriter checkpoints_;
  Scheduler scheduler_;
  std::map<std::string, Job> jobs_;
  std::map<std::string, std::string> bundle_owner_;  // bundle hash -> a job that has it
  std::map<std::string, Sequence> sequences_;
  // What tick() looks at: jobs active and started, and jobs with a storage error. A queued job
  // that has not started, most of a long sequence, costs tick() nothing.
  std::set<std::string> attention_;
  uint64_t jobs_visited_ = 0;
  ChangeBudget change_budget_;
  bool recovering_ = false;  // recover() is loading jobs: previews wait until it is done
  SequencePreviews previews_{options_.ffmpeg};

  // Sequences (job_sequences.cpp): the public requests above fan out to a sequence's frames.
  const std::vector<std::string>* sequence_frames(const std::string& id) const;
  /// The sequence's state from its frames' (a cancelled one's frames still active count as
  /// cancelled).
  wire::JobState sequence_state(const Sequence& q) const;
  wire::JobStatus sequence_status(const std::string& id, const Sequence& q,
                                  uint32_t workers_total, bool with_frames) const;
  wire::JobState cancel_sequence(const std::string& id);
  /// Ends the next slice of a cancelled sequence's frames (at most kCancelSlice frames looked
  /// at, kCancelStartedSlice of them written).
  void cancel_slice(const std::string& id, Sequence& q);
  /// The sequence a frame's job belongs to; nullptr for a job of its own.
  Sequence* sequence_of(const JobSpec& spec);
  const Sequence* sequence_of(const JobSpec& spec) const;
  /// The state of sequence `id` from its sequence.json (recover()); `first_frame`'s priority for
  /// a sequence stored before it kept one. False when its clock was not kept.
  bool recover_sequence(const std::string& id, Sequence& q, const JobRecord& first_frame);
  /// Saves the sequence's state (sequence.json); a failure is logged (the state holds in memory).
  void save_sequence(const std::string& id, const Sequence& q);
  /// A frame of sequence `id` stopped being active: the sequence's clock stops with its last.
  void frame_ended(const std::string& id);
  /// A frame of the sequence got a unit: its clock runs.
  void sequence_started(const JobSpec& frame, Clock::time_point now);
  /// Stops or starts the clocks of the sequence's started frames (its pause); they are in
  /// attention_, so this costs the frames running, not the sequence's length.
  void pause_frames(const std::string& id, bool paused, Clock::time_point now);
  const JobRecord* change_sequence(const std::string& id, std::optional<int32_t> priority,
                                   std::optional<bool> paused);
  void remove_sequence(const std::string& id);
  /// change() of one job, frames included.
  const JobRecord* change_one(const std::string& id, std::optional<int32_t> priority,
                              std::optional<bool> paused, const std::string& by = {});
  wire::JobState retry_sequence(const std::string& id, const std::string& by);
  /// Removes a finished job and its folder (remove() has checked it may go).
  void remove_job(const std::string& id);
  /// The bundle of `hash` was served from folder `gone`, which is removed: serve it from another
  /// job's folder that has it, if any.
  void rebind_bundle(const std::string& hash, const std::string& gone);
  /// Stores the job of every frame of a sequence whose bundle is in `spec`'s folder; throws
  /// std::runtime_error (the frames stored so far are removed).
  std::vector<JobSpec> store_frames(const JobSpec& spec, const FrameList& frames,
                                    const JobRecord& shared, double fps) const;
  /// Queues the sequence's previews (sequence_previews.h): its contact sheet, and its movie once
  /// every frame is done; at recovery (`missing_only`), only those missing.
  void update_previews(const std::string& id, bool missing_only = false);
  /// What the sequence's previews are, for its status.
  std::string previews_note(const std::string& id, const Sequence& q) const;
  /// Admits one job (of its own, or a frame of a sequence); returns its id.
  std::string admit_one(const JobSpec& spec, std::optional<Image> reference, int32_t priority,
                        bool paused, const std::vector<std::string>& warnings, size_t bundle_files,
                        uint64_t bundle_bytes);
  /// Makes the job active (queued, nothing merged) and hands its released units to the
  /// scheduler; `reference` when already read.
  void activate(Job& job, std::optional<Image> reference = std::nullopt);
  /// The job's parts, nothing merged; its reference image is read from the store unless given.
  std::unique_ptr<ActiveJob> make_active(const JobSpec& spec, std::optional<Image> reference);
  /// Gives the scheduler the units of an active job that are released and not merged.
  void schedule(Job& job);
  /// Brings a job made active but not scheduled to the state of its newest usable checkpoint;
  /// false when it has none (it starts from the beginning). Logs what it used and what it could
  /// not.
  bool resume(Job& job);
  /// Queues a checkpoint of the job's merged state; saves its record too when its log has lines
  /// the record on disk lacks (a failed unit's, a worker's), so that a restart keeps them.
  void checkpoint(Job& job);
  /// Counts a failure of `worker` on `unit`; blocks the worker or fails the job past the limits.
  void note_failure(Job& job, const WorkerId& worker, const std::string& key, uint64_t unit,
                    const std::string& why);
  /// Fails the job when every connected worker has been blocked from it for blocked_grace; true
  /// when it did.
  bool fail_if_nobody_can_render(Job& job, Clock::time_point now);
  /// The reference image in `exr`; throws JobRejected unless it is a readable EXR of the film's
  /// size.
  Image check_reference_bytes(const std::string& exr, FilmSize film) const;
  /// Queues the job's image; `wait` returns only once it is on disk.
  void write_image(Job& job, bool wait = false);
  /// How long a running job waits between progressive images (checkpoints): the configured
  /// interval, or longer when the latest one cost more than write_share of it.
  Clock::duration image_interval(const Job& job) const;
  Clock::duration checkpoint_interval(const Job& job) const;
  void on_round_done(Job& job);
  /// What tick() does for one job.
  void tick_job(const std::string& id, Job& job, Clock::time_point now);
  void finish(Job& job, wire::JobState state, const std::string& error,
              StopReason reason = StopReason::kRunning);
  /// Saves the job's record; on failure notes it (storage_error, retried by tick) and returns
  /// false.
  bool save(Job& job);
  /// Notes a storage failure of the job and when to try again (back-off up to 30 s).
  void storage_failed(Job& job, const std::string& what);
  /// The final image and record of a job whose work is over; "" when both are on disk, else why.
  std::string store_final(Job& job, const JobRecord& final_record, bool image);

  /// Adds a line to the job's log (job_log.h; saved with its record). A routine line (accepted,
  /// started, done) is left out of a sequence's frames: their times say as much, and a sequence
  /// may have 100,000 of them.
  static void note(JobRecord& record, const char* level, std::string text, bool routine = false);
  /// The log's first lines: the job accepted (`units` of work, stopping by `stop`), and the
  /// scene's warnings.
  static void note_accepted(JobRecord& record, uint64_t units, const std::string& stop,
                            const std::vector<std::string>& warnings);
  /// The wall clock in Unix milliseconds.
  static int64_t wall_ms();
  /// Seconds of rendering: the record's once the job is over.
  static double elapsed(const Job& job);
  wire::JobStatus make_status(const Job& job, uint32_t workers_total) const;
  static uint32_t workers_active(const ActiveJob& job);
  std::string name_of(const WorkerId& worker) const;
};

}  // namespace rayfarm::master
