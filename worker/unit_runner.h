#pragma once
// Renders leased units: `capacity()` threads of their own, for the worker's lifetime, share one
// TBB arena of the chosen size, so that one unit's last rows overlap the next unit's first and the
// reactor's thread stays free for heartbeats. The scene and Renderer of the current job are kept
// between units. Every unit started comes back from take_finished() exactly once, with its result
// or the reason it failed. start(), in_hand() and the take_* calls belong to one thread (the
// reactor's).
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <tbb/task_arena.h>

#include "proto/rayfarm.pb.h"

namespace rayfarm::worker {

class UnitRunner {
 public:
  /// A unit rendered, or not.
  struct Finished {
    wire::WorkUnit unit;
    wire::UnitResult result;  ///< when ok
    std::string error;        ///< why it failed, when not ok
    bool ok = false;
  };

  /// `threads` 0 = all hardware threads; `units_at_once` 0 = 2 with two or more threads, else 1.
  /// Scenes are read from `<cache_dir>/<bundle hash>/<scene path>`.
  UnitRunner(uint32_t threads, uint32_t units_at_once, std::filesystem::path cache_dir);
  /// Finishes the units being rendered; drops those not started.
  ~UnitRunner();
  UnitRunner(const UnitRunner&) = delete;
  UnitRunner& operator=(const UnitRunner&) = delete;

  int threads() const { return arena_.max_concurrency(); }
  /// Units rendered at once.
  size_t capacity() const { return capacity_; }
  /// Units started and not taken back yet.
  size_t in_hand() const { return in_hand_; }

  void start(wire::WorkUnit unit);
  /// The units finished since the last call, waiting up to `wait` for one when none has.
  std::vector<Finished> take_finished(std::chrono::milliseconds wait);
  /// The units finished since the last call, waiting for one for as long as it takes.
  std::vector<Finished> take_finished();

  /// Logs what this worker did for its current job (as it also does when it moves to another).
  void log_job_stats();

 private:
  struct Prepared;
  /// What this worker did for one job, for the line logged when it moves on.
  struct JobStats {
    std::string job_id;
    uint64_t units = 0;
    uint64_t samples = 0;
    double seconds = 0.0;
  };

  std::filesystem::path cache_dir_;
  tbb::task_arena arena_;
  size_t capacity_;
  size_t in_hand_ = 0;  // the reactor's thread only

  std::mutex prepare_mutex_;  // one job is prepared at a time
  std::mutex mutex_;          // guards what follows
  std::condition_variable work_cv_;
  std::deque<wire::WorkUnit> queue_;  // units for the render threads
  std::condition_variable finished_cv_;
  std::vector<Finished> finished_;  // not taken yet, in the order they finished
  bool shutting_down_ = false;
  std::shared_ptr<const Prepared> prepared_;
  JobStats stats_;
  std::vector<std::thread> render_threads_;  // last: started once the rest is ready

  void render_loop();
  Finished render(wire::WorkUnit unit);
  /// The scene and renderer for `unit`'s job, loaded on first use and kept while the job lasts.
  std::shared_ptr<const Prepared> prepare(const wire::WorkUnit& unit);
  void log_job_stats_locked();
};

}  // namespace rayfarm::worker
