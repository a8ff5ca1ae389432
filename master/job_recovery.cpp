// Recovery: checkpoints of running jobs, and what a starting master does with the jobs of its
// data dir (resume each unfinished one from its newest usable checkpoint, or start it over).
#include <algorithm>
#include <set>

#include "common/util/log.h"
#include "master/job_manager.h"
#include "master/job_text.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
using namespace detail;

bool JobManager::recover_sequence(const std::string& id, Sequence& q,
                                  const JobRecord& first_frame) {
  const SequenceRecord r = store_.load_sequence(id);
  // A sequence stored before its state was its own: its first frame's priority; its frames'
  // pauses stay theirs.
  q.priority = r.has_state ? r.priority : first_frame.priority;
  q.paused = r.has_state && r.paused;
  q.cancelled_unix_ms = r.cancelled_unix_ms;
  q.elapsed_before = std::max(0.0, r.elapsed_seconds);
  return r.elapsed_seconds >= 0;
}

size_t JobManager::recover() {
  size_t restarted = 0;
  std::set<std::string> unknown_elapsed;  // sequences whose clock was not kept
  recovering_ = true;  // a frame finished here joins its sequence's previews once all are loaded
  for (JobRecord& record : store_.load_records()) {
    const std::string id = record.spec.id;
    Job job;
    job.record = std::move(record);
    if (job.record.unreadable) {  // listed as it is, with its cause; never saved over
      jobs_.emplace(id, std::move(job));
      continue;
    }
    const std::string& sequence = job.record.spec.sequence;
    if (!sequence.empty() && !store_.sequence_stored(sequence)) {
      // A sequence whose submission a crash cut short: its client was never told of it.
      log_jobs()->warn("job {}: frame of sequence {}, whose submission never completed; removed",
                       id, sequence);
      std::error_code ec;
      fs::remove_all(store_.job_dir(id), ec);
      fs::remove_all(store_.job_dir(sequence), ec);
      continue;
    }
    bundle_owner_.emplace(job.record.spec.bundle_hash, JobStore::bundle_holder(job.record.spec));
    if (!sequence.empty()) {
      auto [q, fresh] = sequences_.try_emplace(sequence);
      if (fresh && !recover_sequence(sequence, q->second, job.record)) {
        unknown_elapsed.insert(sequence);
      }
      q->second.frames.push_back(id);
      q->second.queued_unix_ms = std::max(
          {q->second.queued_unix_ms, job.record.spec.submitted_unix_ms, job.record.queued_unix_ms});
      // A sequence that did not keep its clock: its frames' times added up, at most its wall time.
      if (unknown_elapsed.count(sequence)) q->second.elapsed_before += job.record.elapsed_seconds;
      // A frame queued before the sequence's latest cancel was cancelled (the cancel writes the
      // records only of the frames that had started; a stop may also have cut it short).
      const int64_t queued = job.record.queued_unix_ms > 0 ? job.record.queued_unix_ms
                                                           : job.record.spec.submitted_unix_ms;
      if (is_active_state(job.record.state) && queued < q->second.cancelled_unix_ms) {
        const bool started = job.record.state == wire::JOB_RUNNING;
        job.record.state = wire::JOB_CANCELLED;
        job.record.paused = false;
        job.record.error = "cancelled by a client";
        job.record.stop_reason = stop_reason_name(StopReason::kCancelled);
        job.record.finished_unix_ms = q->second.cancelled_unix_ms;
        if (started) save(job);  // what it rendered stays; nothing else said it ended
      }
    }
    if (is_active_state(job.record.state)) {
      if (!store_.load_bundle(JobStore::bundle_holder(job.record.spec))) {
        job.record.state = wire::JOB_FAILED;
        job.record.paused = false;
        job.record.error = "the job's bundle is missing from the data dir";
        job.record.finished_unix_ms = wall_ms();
        note(job.record, "error", "failed when the master started: " + job.record.error);
        log_jobs()->error("job {}: {}; marked failed", id, job.record.error);
        save(job);
      } else {
        const bool was_running = job.record.state == wire::JOB_RUNNING;
        job.record.state = wire::JOB_QUEUED;
        job.active = make_active(job.record.spec, std::nullopt);
        ++restarted;
        bool resumed = false;
        try {
          resumed = resume(job);
        } catch (const std::exception& e) {  // e.g. out of memory: start over rather than stop
          log_jobs()->error("job {}: its checkpoint cannot be loaded ({}); starting over", id,
                            e.what());
          job.record.state = wire::JOB_QUEUED;
          job.active = make_active(job.record.spec, std::nullopt);
        }
        schedule(job);
        if (!resumed) {
          if (was_running) {
            log_jobs()->info(
                "job {} restarted from the beginning ('{}', {}x{}, {} spp): no usable checkpoint",
                id, job.record.spec.name, job.record.spec.film.width, job.record.spec.film.height,
                job.record.spec.settings.spp);
          } else {
            log_jobs()->info("job {} queued again ('{}'): it had not started", id,
                             job.record.spec.name);
          }
        }
        save(job);
      }
    } else if (job.record.state == wire::JOB_DONE && job.record.stop_reason.empty()) {
      // A record from before stopping rules: the job ran every unit.
      const JobSpec& s = job.record.spec;
      job.record.units_done = UnitGrid(s.film, s.tile_size, s.settings.spp, s.pass_spp).size();
      job.record.spp_min = s.settings.spp;
      job.record.spp_mean = s.settings.spp;
    }
    if (!is_active_state(job.record.state)) remove_checkpoints(store_.job_dir(id));  // stale
    auto [it, inserted] = jobs_.emplace(id, std::move(job));
    // A job whose last unit was merged before the crash, but not yet recorded as done.
    if (inserted && it->second.active && it->second.active->planner.finished()) {
      finish(it->second, wire::JOB_DONE, "", it->second.active->planner.reason());
    }
  }
  // A sequence's frames in frame order (their folders sort by name: "j0007.-001" after "0001").
  for (auto& [sequence, q] : sequences_) {
    std::sort(q.frames.begin(), q.frames.end(), [&](const std::string& a, const std::string& b) {
      return jobs_.at(a).record.spec.frame.value_or(0) < jobs_.at(b).record.spec.frame.value_or(0);
    });
    update_previews(sequence, /*missing_only=*/true);  // e.g. a stop while one was being made
  }
  recovering_ = false;
  return restarted;
}

bool JobManager::resume(Job& job) {
  const JobSpec& s = job.record.spec;
  const UnitGrid& grid = job.active->grid();
  // The merged state a checkpoint describes, checked against the job's settings and itself.
  struct Restored {
    Merger merger;
    PassPlanner planner;
  };
  auto rebuild = [&](const Checkpoint& c) {
    if (c.job_id != s.id || c.width != s.film.width || c.height != s.film.height ||
        c.tile_size != s.tile_size || c.spp != s.settings.spp || c.pass_spp != s.pass_spp) {
      throw CheckpointError(fmt::format(
          "it is of job '{}' {}x{}, tile {}, {} spp in passes of {}, not of this job's settings",
          c.job_id, c.width, c.height, c.tile_size, c.spp, c.pass_spp));
    }
    if (!(c.elapsed_seconds >= 0) || c.rows.size() > grid.size() + 1) {
      throw CheckpointError("inconsistent: bad elapsed time or error rows");
    }
    Restored out{Merger(grid), PassPlanner(grid, s.stop)};
    try {
      out.merger.restore(c.merged, c.sum, c.sum_sq, c.nonfinite, c.rays);
      out.planner.import_state(c.planner, out.merger.merged_units());
    } catch (const std::invalid_argument& e) {
      throw CheckpointError(std::string("inconsistent: ") + e.what());
    }
    return out;
  };
  std::vector<std::string> problems;
  auto loaded = load_newest_checkpoint(store_.job_dir(s.id), problems,
                                       [&](const Checkpoint& c) { rebuild(c); });
  for (const std::string& problem : problems) {
    log_jobs()->error("job {}: cannot use checkpoint {}{}", s.id, problem,
                      loaded ? fmt::format("; falling back to {}", loaded->file.string())
                             : std::string("; no other checkpoint to fall back to"));
  }
  if (!loaded) return false;
  const Checkpoint& c = loaded->checkpoint;
  ActiveJob& a = *job.active;
  Restored restored = rebuild(c);
  a.merger = std::move(restored.merger);
  a.planner = std::move(restored.planner);
  a.tracker.estimate_all(a.merger.film());
  a.rows = c.rows;
  a.rounds_recorded = c.rounds_recorded;
  a.samples_recorded = c.samples_recorded;
  job.checkpoint_sequence = c.sequence;
  checkpoints_.set_newest_slot(s.id, loaded->slot);
  if (c.elapsed_seconds > 0 || a.merger.merged_count() > 0) {
    a.start_time = Clock::now() - std::chrono::duration_cast<Clock::duration>(
                                      std::chrono::duration<double>(c.elapsed_seconds));
    job.record.state = wire::JOB_RUNNING;
    attention_.insert(s.id);  // started: tick() looks after it
  }
  log_jobs()->info(
      "job {} resumed from checkpoint at {}/{} units, pass {} ({:.1f} s rendered; {}, checkpoint "
      "{})",
      s.id, a.merger.merged_count(), grid.size(),
      a.planner.rounds_complete(a.merger.merged_units()), c.elapsed_seconds, loaded->file.string(),
      c.sequence);
  if (a.merger.merged_count() > 0) write_image(job);
  return true;
}

void JobManager::checkpoint(Job& job) {
  const auto start = Clock::now();
  const JobSpec& s = job.record.spec;
  const Merger& m = job.active->merger;
  Checkpoint c;
  c.sequence = ++job.checkpoint_sequence;
  c.job_id = s.id;
  c.width = s.film.width;
  c.height = s.film.height;
  c.tile_size = s.tile_size;
  c.spp = s.settings.spp;
  c.pass_spp = s.pass_spp;
  c.elapsed_seconds = job.active->elapsed();
  c.merged = m.merged_units().to_bytes();
  c.sum = m.film().sum();
  c.sum_sq = m.film().sum_sq();
  c.nonfinite = m.film().nonfinite();
  c.rays = m.film().rays();
  c.planner = job.active->planner.export_state();
  c.rows = job.active->rows;
  c.rounds_recorded = job.active->rounds_recorded;
  c.samples_recorded = job.active->samples_recorded;
  checkpoints_.submit(store_.job_dir(s.id), std::move(c));
  job.active->checkpoint_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  job.active->checkpoint_due = false;
  job.active->last_checkpoint = Clock::now();
  if (job.record.log.version != job.log_saved && !job.record_unsaved) save(job);
}

size_t JobManager::shutdown() {
  size_t count = 0;
  for (auto& [id, job] : jobs_) {
    if (!job.active || !job.active->started()) continue;  // finished, or nothing to keep yet
    if (job.active->dirty) write_image(job);
    checkpoint(job);
    ++count;
  }
  // Each sequence's clock, as far as it got.
  for (const auto& [id, q] : sequences_) {
    if (q.active > 0) save_sequence(id, q);
  }
  checkpoints_.flush();
  writer_.flush();
  if (count) {
    log_jobs()->info(
        "{} running job{} checkpointed; they resume there when the master starts again", count,
        count == 1 ? "" : "s");
  }
  return count;
}

}  // namespace rayfarm::master
