#pragma once
// A job while it is queued or running: its merger (which units are merged, and the film), its
// pass planner (which units are released), its error record, its timers and its failures. The
// job manager (job_manager.h) holds one exactly while the job is active; a finished job keeps
// only its record.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/image/exr.h"
#include "common/report/error_tracker.h"
#include "common/schedule/pass_planner.h"
#include "master/job_store.h"
#include "master/merger.h"
#include "master/scheduler.h"
#include "master/unit_book.h"

namespace rayfarm::master {

struct ActiveJob {
  using Clock = std::chrono::steady_clock;

  /// How a job whose work is over will end. It is reported finished only once its final image
  /// and record are on disk; until then it stays running, keeps its checkpoints and retries.
  struct Finishing {
    wire::JobState state = wire::JOB_DONE;
    std::string error;
    StopReason reason = StopReason::kSpp;
    double elapsed = 0.0;
  };

  /// The job of `spec`, nothing merged; `reference` measures its error when given.
  ActiveJob(const JobSpec& spec, std::optional<Image> reference)
      : merger(UnitGrid(spec.film, spec.tile_size, spec.settings.spp, spec.pass_spp)),
        planner(merger.grid(), spec.stop),
        tracker(merger.grid().tiles(), std::move(reference)) {}

  const UnitGrid& grid() const { return merger.grid(); }
  /// A unit has been handed out (the render's clock runs).
  bool started() const { return start_time.has_value(); }
  /// Seconds of rendering so far: from the first unit handed out, less the time the job spent
  /// paused since (its time limit and rates leave the pauses out; units that finish during a
  /// pause count on the stopped clock).
  double elapsed() const {
    if (!start_time) return 0.0;
    const Clock::time_point now = Clock::now();
    Clock::duration d = now - *start_time - paused_for;
    if (paused_since) d -= now - std::max(*paused_since, *start_time);
    return std::max(0.0, std::chrono::duration<double>(d).count());
  }
  /// The job's clock stops (pause) and runs again (resume); each is a no-op when repeated.
  void pause(Clock::time_point now) {
    if (!paused_since) paused_since = now;
  }
  void resume(Clock::time_point now) {
    if (!paused_since) return;
    if (start_time) paused_for += now - std::max(*paused_since, *start_time);
    paused_since.reset();
  }
  /// Appends the error row of the film as it is now. Every merge updated its tile's estimate
  /// (update_tile), so the image's is a sum over tiles here; the row still counts samples, and
  /// compares with the reference when there is one.
  const ErrorRow& record_row() {
    rows.push_back(tracker.record(merger.film(), elapsed(), /*tiles_current=*/true));
    samples_recorded = merger.samples_merged();
    return rows.back();
  }

  Merger merger;               // which units are merged, and the film
  PassPlanner planner;         // which units the stopping rules release
  ErrorTracker tracker;        // computes the error rows
  std::vector<ErrorRow> rows;  // error against time, one row per round of passes
  uint32_t rounds_recorded = 0;
  uint64_t samples_recorded = 0;  // pixel samples behind the last error row

  std::optional<Clock::time_point> start_time;    // when the first unit was handed out
  std::optional<Clock::time_point> paused_since;  // paused now, since then
  Clock::duration paused_for{0};                  // paused after start_time, before now
  Clock::time_point last_write;                   // of the image
  bool dirty = false;                             // merged since the last image write
  bool checkpoint_due = false;                    // merged since the last checkpoint
  Clock::time_point last_checkpoint = Clock::now();
  double image_seconds = 0;       // the reactor's part of the last image write (its snapshot)
  double checkpoint_seconds = 0;  // the reactor's part of the last checkpoint (its copy)
  std::map<WorkerId, Clock::time_point> contributors;  // last result from each worker

  // Failures: per unit, the keys (or workers, without keys) it failed under and their messages;
  // per key, how many.
  std::map<uint64_t, std::map<std::string, std::string>> unit_failures;
  std::map<std::string, int> worker_failures;
  std::optional<Clock::time_point> all_blocked_since;  // every connected worker is blocked
  // Who was leased each unit not merged yet, connection and key (a lost worker's late result is
  // still its own; a peer that takes over its connection id with another key is not).
  std::unordered_map<uint64_t, std::vector<std::pair<WorkerId, std::string>>> lease_history;

  std::optional<Finishing> finishing;  // the work is over, the final writes are not
  UnitBook book;  // its units' history and its workers' shares, for its detail view
};

}  // namespace rayfarm::master
