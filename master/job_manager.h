#pragma once
// The master's jobs, without sockets: accepting a job (the scene is validated first), handing out
// its units through the Scheduler, merging results through a Merger per job, writing the
// progressive image and the job's record through the JobStore, and answering status queries.
// The broker (broker.h) calls it from its one thread; nothing here is thread-safe.
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "master/image_writer.h"
#include "master/job_store.h"
#include "master/merger.h"
#include "master/scheduler.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master {

/// A job that cannot be accepted; what() is the cause for the client (e.g. the parser's message).
class JobRejected : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct JobManagerOptions {
  /// While results arrive, the image is rewritten at least this often (besides every pass).
  std::chrono::milliseconds image_interval{3000};
  /// A unit that fails on this many attempts fails its job.
  int max_unit_failures = 3;
  /// How workers are named in logs; by default the hex of their id.
  std::function<std::string(const WorkerId&)> worker_name;
};

class JobManager {
 public:
  using Clock = std::chrono::steady_clock;

  JobManager(JobStore& store, JobManagerOptions options = {});

  /// Loads the jobs of the data dir: finished ones as they were, unfinished ones from the start
  /// (partial sums are not stored). Returns how many were restarted.
  size_t recover();

  /// Validates and accepts a job; returns its id. Throws JobRejected naming the cause.
  std::string submit(const wire::SubmitJob& request);

  /// The next unit for `worker`, leased to it; nullopt when no job has pending units.
  std::optional<wire::WorkUnit> next_unit(const WorkerId& worker);
  bool has_pending() const { return scheduler_.has_pending(); }

  /// Merges a result from `worker` (who need not hold the unit: a late result from a worker that
  /// was declared lost still counts when the unit is not merged yet).
  MergeOutcome on_result(const WorkerId& worker, const wire::UnitResult& result);
  /// A worker could not render a unit: requeue it, or fail the job after repeated failures.
  void on_unit_failed(const WorkerId& worker, const wire::UnitFailed& failed);
  /// Takes back the leases of a worker that is lost or gone; returns how many were requeued.
  size_t release_worker(const WorkerId& worker);

  /// Cancels a job; the state afterwards, or nullopt when the job is unknown.
  std::optional<wire::JobState> cancel(const std::string& id);
  /// Status of one job; nullopt when unknown. `workers_total` is the master's worker count.
  std::optional<wire::JobStatus> status(const std::string& id, uint32_t workers_total) const;
  /// Status of every job, in id order.
  std::vector<wire::JobStatus> list(uint32_t workers_total) const;
  /// The job's current image; throws JobRejected when unknown or nothing is written yet.
  wire::ImageData image(const std::string& id) const;
  /// The bundle with this hash, from the store; nullopt when no job has it.
  std::optional<wire::Bundle> bundle(const std::string& hash) const;

  /// Writes the images that are due (results merged since the last write, interval passed).
  void tick();
  /// Jobs queued or running.
  size_t active_jobs() const;

 private:
  struct Job {
    JobRecord record;
    std::unique_ptr<Merger> merger;  // while queued or running
    bool started = false;
    Clock::time_point start_time;
    Clock::time_point last_write;
    bool dirty = false;  // merged since the last image write
    uint32_t passes_logged = 0;
    std::map<uint64_t, int> failures;
    uint64_t units_done = 0;  // kept when the merger is released
    uint32_t spp_done = 0;
    std::map<WorkerId, Clock::time_point> contributors;  // last result from each worker
  };

  JobStore& store_;
  JobManagerOptions options_;
  ImageWriter writer_;
  Scheduler scheduler_;
  std::map<std::string, Job> jobs_;
  std::map<std::string, std::string> bundle_owner_;  // bundle hash -> a job that has it

  void activate(Job& job);
  /// Queues the job's image; `wait` returns only once it is on disk.
  void write_image(Job& job, bool wait = false);
  void on_pass_done(Job& job);
  void finish(Job& job, wire::JobState state, const std::string& error);
  void save(const Job& job);
  double elapsed(const Job& job) const;
  wire::JobStatus make_status(const Job& job, uint32_t workers_total) const;
  uint32_t workers_active(const Job& job) const;
  std::string name_of(const WorkerId& worker) const;
};

}  // namespace rayfarm::master
