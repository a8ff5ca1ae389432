// The job lifecycle: making a job active, rounds of passes, counting failures, and cancel, remove
// and retry. Leasing units and merging their results (job_units.cpp), admission, recovery, status
// and the end of a job have files of their own (job_manager.h).
#include <algorithm>

#include "common/net/frames.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "master/eta.h"
#include "master/job_manager.h"
#include "master/job_text.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;
using namespace detail;

JobManager::JobManager(JobStore& store, JobManagerOptions options)
    : store_(store), options_(std::move(options)) {}

std::string JobManager::name_of(const WorkerId& worker) const {
  return options_.worker_name ? options_.worker_name(worker) : net::peer_label(worker);
}

std::unique_ptr<ActiveJob> JobManager::make_active(const JobSpec& s,
                                                   std::optional<Image> reference) {
  if (s.has_reference && !reference) {
    try {
      reference = load_reference(store_.reference_path(s.id), s.film);
    } catch (const std::exception& e) {
      log_jobs()->error("job {}: its reference image cannot be read ({}); the error is only "
                        "estimated",
                        s.id, e.what());
    }
  }
  return std::make_unique<ActiveJob>(s, std::move(reference));
}

void JobManager::activate(Job& job, std::optional<Image> reference) {
  job.active = make_active(job.record.spec, std::move(reference));
  job.record.state = wire::JOB_QUEUED;
  schedule(job);
}

void JobManager::schedule(Job& job) {
  const std::string& id = job.record.spec.id;
  ActiveJob& a = *job.active;
  scheduler_.add_job(id, job.record.spec.sequence, job.record.spec.frame.value_or(0));
  scheduler_.set_run_stride(id, a.grid().tile_count());
  scheduler_.set_priority(id, job.record.priority);
  scheduler_.set_paused(id, job.record.paused);
  Sequence* q = sequence_of(job.record.spec);
  // The sequence's priority and pause are its frames' (set once for the group).
  if (q != nullptr) {
    scheduler_.set_group(job.record.spec.sequence, q->priority, q->paused || q->cancelled);
  }
  // A paused sequence stops the clocks of its started frames only: one not started yet starts
  // its clock with its first unit, which a held sequence does not give it (and a resume visits
  // the started frames alone).
  if (job.record.paused || (q != nullptr && q->paused && a.started())) a.pause(Clock::now());
  a.planner.take_released();  // handed over below, with every other released unit
  if (a.merger.merged_count() == 0 && !a.planner.gated()) {
    scheduler_.release_all(id, a.grid().size());
  } else {
    std::vector<uint64_t> units;
    for (uint64_t unit = 0; unit < a.grid().size(); ++unit) {
      if (a.planner.is_released(unit) && !a.merger.merged(unit)) units.push_back(unit);
    }
    scheduler_.release(id, units);
  }
  // Counted once the frame is scheduled: a throw above leaves the sequence's count as it was.
  if (q != nullptr) {
    if (job.record.paused) q->paused_alone.insert(id);
    ++q->active;
  }
}

void JobManager::on_round_done(Job& job) {
  ActiveJob& a = *job.active;
  const Merger& m = a.merger;
  const PassPlanner& planner = a.planner;
  const JobSpec& s = job.record.spec;
  const uint32_t rounds_before = a.rounds_recorded;
  a.rounds_recorded = planner.rounds_complete(m.merged_units());
  const double seconds = a.elapsed();
  const ErrorRow& row = a.record_row();
  const double eta =
      estimate_eta(s.stop, static_cast<double>(m.grid().samples_total() - m.samples_merged()),
                   row.samples_per_s, seconds, a.rows);
  // The per-tile figure: the tile with the largest estimated error, and where it is.
  const TiledErrorEstimate& tiles = a.tracker.estimate();
  const int worst_tile = tiles.worst_tile();
  const double worst = worst_tile >= 0 ? tiles.tile(worst_tile).rel_mse : -1.0;
  const TileRect worst_rect = worst_tile >= 0 ? tiles.tiles()[worst_tile] : TileRect{};
  log_jobs()->info(
      "job {} pass {}/{} done: {:.1f} spp, estimated relMSE {:.3g} (RMSE {:.3g}){}{}{}, {}, ETA "
      "{:.1f} s, {} workers active",
      s.id, a.rounds_recorded, m.grid().pass_count(), row.spp, row.est_rel_mse, row.est_rmse,
      worst >= 0
          ? fmt::format(", worst tile at ({}, {}) {:.3g}", worst_rect.x0, worst_rect.y0, worst)
          : "",
      planner.gated()
          ? fmt::format(", {}/{} tiles converged", planner.tiles_converged(), planner.tile_count())
          : "",
      row.ref_rel_mse ? fmt::format(", measured relMSE {:.3g}", *row.ref_rel_mse) : "",
      human_rate(row.samples_per_s), eta, workers_active(a));
  // A round's image and checkpoint are written now unless one was written within its interval
  // (the first round's image always is, the first whole picture): a large farm completes rounds
  // of a large image several times a second, and each image or checkpoint is a pass over the
  // whole film on this thread. Until then they are due (dirty, checkpoint_due) and tick() writes
  // them when the interval is up.
  const Clock::time_point now = Clock::now();
  if (rounds_before == 0 || now - a.last_write >= image_interval(job)) write_image(job);
  if (options_.checkpoint_interval.count() == 0 ||
      now - a.last_checkpoint >= checkpoint_interval(job)) {
    checkpoint(job);
  }
}

bool JobManager::on_unit_failed(const WorkerId& worker, const wire::UnitFailed& failed,
                                const std::string& key) {
  auto it = jobs_.find(failed.job_id());
  if (it == jobs_.end() || !it->second.active) return false;
  Job& job = it->second;
  const UnitRef ref{failed.job_id(), failed.unit_id()};
  std::string reason = protocol::printable(failed.reason(), 500);
  if (reason.empty()) reason = "(no reason given)";
  if (!scheduler_.holds(ref, worker)) {
    log_jobs()->debug("job {} unit {}: failure report from {} ignored: it does not hold the unit",
                      ref.job, ref.unit, name_of(worker));
    return false;
  }
  log_jobs()->warn("job {} unit {} failed on {}: {}", ref.job, ref.unit, name_of(worker), reason);
  job.active->book.failed(ref.unit, name_of(worker), reason);
  {
    const UnitGrid::Unit u = job.active->grid().unit(ref.unit);
    note(job.record, "warning",
         fmt::format("unit {} (tile {},{} to {},{}, pass {}) failed on {}: {}", ref.unit, u.rect.x0,
                     u.rect.y0, u.rect.x1, u.rect.y1, u.pass, name_of(worker), reason));
  }
  for (const uint64_t unit : scheduler_.lease_of(ref, worker)) {  // the whole lease failed
    scheduler_.requeue(UnitRef{ref.job, unit}, worker);
  }
  note_failure(job, worker, key, ref.unit, reason);
  return true;
}

void JobManager::note_failure(Job& job, const WorkerId& worker, const std::string& key,
                              uint64_t unit, const std::string& why) {
  const std::string& id = job.record.spec.id;
  if (!job.active) return;
  ActiveJob& a = *job.active;
  // Failures count per key: every connection made with one key is one worker here, so that one
  // key can block only itself and never fail a job alone.
  const std::string& who = key.empty() ? worker : key;
  const std::string label =
      key.empty() ? name_of(worker)
                  : fmt::format("key '{}' ({})", protocol::printable(key), name_of(worker));
  const int worker_count = ++a.worker_failures[who];
  auto& on_unit = a.unit_failures[unit];
  if (!on_unit.count(who) && on_unit.size() >= 64) return;  // enough to decide; bounded memory
  on_unit[who] = label + ": " + why;
  if (static_cast<int>(on_unit.size()) >= options_.max_unit_failures) {
    std::string messages;
    for (const auto& [w, message] : on_unit) {
      messages += fmt::format("{}{}", messages.empty() ? "" : "; ", message);
    }
    finish(job, wire::JOB_FAILED,
           fmt::format("unit {} failed on {} different workers: {}", unit, on_unit.size(),
                       messages));
    return;
  }
  if (worker_count >= options_.max_worker_failures && !scheduler_.is_blocked(id, who)) {
    scheduler_.block(id, who);
    log_jobs()->warn(
        "job {}: {} blocked from the job after {} failures (last: {}); it gets "
        "other jobs' units",
        id, label, worker_count, why);
    note(job.record, "warning",
         fmt::format("{} blocked from the job after {} failures; it gets other jobs' units", label,
                     worker_count));
    fail_if_nobody_can_render(job, Clock::now());
  }
}

bool JobManager::fail_if_nobody_can_render(Job& job, Clock::time_point now) {
  // With every connected worker blocked (one key shared by the whole farm, or a scene that fails
  // everywhere), the job could never finish: once that has lasted the grace, it fails.
  const std::string& id = job.record.spec.id;
  if (!job.active || job.active->finishing || job.active->worker_failures.empty() ||
      !options_.connected_workers) {
    return false;
  }
  ActiveJob& a = *job.active;
  const std::vector<std::string> connected = options_.connected_workers();
  const bool all_blocked = !connected.empty() &&
                           std::all_of(connected.begin(), connected.end(),
                                       [&](const auto& w) { return scheduler_.is_blocked(id, w); });
  if (!all_blocked) {
    a.all_blocked_since.reset();
    return false;
  }
  if (!a.all_blocked_since) a.all_blocked_since = now;
  if (now - *a.all_blocked_since < options_.blocked_grace) return false;
  std::string last;
  for (const auto& [unit, on_unit] : a.unit_failures) {
    for (const auto& [who, message] : on_unit) last = message;
  }
  finish(job, wire::JOB_FAILED,
         fmt::format("every connected worker ({}) has been blocked from the job for {:g} s after "
                     "{} failures each; the last: {}",
                     connected.size(), options_.blocked_grace.count() / 1000.0,
                     options_.max_worker_failures, last));
  return true;
}

size_t JobManager::release_worker(const WorkerId& worker, const std::string& why) {
  for (auto& [id, job] : jobs_) {
    if (job.active) job.active->contributors.erase(worker);
  }
  const auto units = scheduler_.release_worker(worker);
  if (units.empty()) return 0;
  std::string list;
  for (const auto& u : units)
    list += fmt::format("{}{} unit {}", list.empty() ? "" : ", ", u.job, u.unit);
  log_scheduler()->warn("requeued {} unit{} of {}: {}", units.size(), units.size() == 1 ? "" : "s",
                        name_of(worker), list);
  // One line in each job's log: how many of its units went back, and why.
  std::map<std::string, size_t> per_job;
  for (const auto& u : units) ++per_job[u.job];
  for (const auto& [id, count] : per_job) {
    auto it = jobs_.find(id);
    if (it == jobs_.end()) continue;
    note(it->second.record, "warning",
         fmt::format("{} unit{} of {} back in the queue: {}", count, count == 1 ? "" : "s",
                     name_of(worker), why));
  }
  return units.size();
}

std::optional<wire::JobState> JobManager::cancel(const std::string& id, const std::string& by) {
  if (sequence_frames(id)) return cancel_sequence(id);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return std::nullopt;
  if (it->second.active) finish(it->second, wire::JOB_CANCELLED, "cancelled by " + requester(by));
  return it->second.record.state;
}

void JobManager::remove(const std::string& id) {
  if (sequence_frames(id)) return remove_sequence(id);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) throw JobRejected("unknown job '" + id + "'");
  Job& job = it->second;
  if (job.active) {
    throw JobRejected(fmt::format("job {} is {}: cancel it first", id,
                                  protocol::job_state_name(job.record.state)));
  }
  if (sequence_frames(job.record.spec.sequence)) {
    throw JobRejected(fmt::format("job {} is frame {} of sequence {}: remove the sequence", id,
                                  job.record.spec.frame.value_or(0), job.record.spec.sequence));
  }
  remove_job(id);
}

void JobManager::remove_job(const std::string& id) {
  auto it = jobs_.find(id);
  Job& job = it->second;
  writer_.flush();  // no image of it is still on its way to the folder
  // Nor is the removal of its checkpoints, which ended the job: a file deleted under remove_all's
  // feet made it fail (ENOENT) now and then.
  checkpoints_.flush();
  std::error_code ec;
  fs::remove_all(store_.job_dir(id), ec);
  if (ec) {
    throw JobRejected(
        fmt::format("cannot remove {}: {}", store_.job_dir(id).string(), ec.message()));
  }
  const std::string hash = job.record.spec.bundle_hash;
  const bool frame = !job.record.spec.sequence.empty();
  jobs_.erase(it);
  attention_.erase(id);
  // A frame's bundle is its sequence's, which remove_sequence() rebinds once it is gone; a
  // sequence logs its removal once.
  if (!frame) rebind_bundle(hash, id);
  log_jobs()->log(frame ? spdlog::level::debug : spdlog::level::info, "job {} removed with its files",
                  id);
}

wire::JobState JobManager::retry(const std::string& id, const std::string& by) {
  if (sequence_frames(id)) return retry_sequence(id, by);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) throw JobRejected("unknown job '" + id + "'");
  Job& job = it->second;
  const wire::JobState state = job.record.state;
  if (job.record.unreadable) {
    throw JobRejected("job " + id + " cannot be retried: " + job.record.error);
  }
  if (state != wire::JOB_FAILED && state != wire::JOB_CANCELLED) {
    throw JobRejected(
        fmt::format("job {} is {}: only a failed or cancelled job can be retried{}", id,
                    protocol::job_state_name(state),
                    state == wire::JOB_DONE ? " (submit it again to render more)" : ""));
  }
  Sequence* q = sequence_of(job.record.spec);
  if (q != nullptr && q->cancelled) {
    throw JobRejected(fmt::format(
        "job {} is frame {} of sequence {}, which is being cancelled ({} frames left to end): "
        "retry it in a moment",
        id, job.record.spec.frame.value_or(0), job.record.spec.sequence, q->active));
  }
  // A sequence's bundle is checked once for all its frames (retry_sequence).
  if ((q == nullptr || !q->retrying) &&
      !store_.load_bundle(JobStore::bundle_holder(job.record.spec))) {
    throw JobRejected("job " + id + " cannot be retried: its bundle is missing from the data dir");
  }
  writer_.flush();
  for (const char* name : {"image.exr", "image.png", "error.csv", "error.png"}) {
    std::error_code ec;
    fs::remove(store_.job_dir(id) / name, ec);
  }
  JobRecord& r = job.record;
  const JobSpec spec = r.spec;
  const int32_t priority = r.priority;
  JobLog log = std::move(r.log);  // the job's history goes on
  r = JobRecord{};
  r.spec = spec;
  r.log = std::move(log);
  note(r, "info",
       "queued again by " + requester(by) + ": retried after it " +
           (state == wire::JOB_FAILED ? "failed" : "was cancelled"));
  r.priority = priority;  // a retried job keeps its place among the others, and runs
  if (q != nullptr) {
    // Queued after the sequence's latest cancel, which a restart must not apply to it.
    r.queued_unix_ms = std::max(wall_ms(), q->cancelled_unix_ms + 1);
    q->queued_unix_ms = std::max(q->queued_unix_ms, r.queued_unix_ms);
  }
  job.storage_error.clear();
  job.record_unsaved = false;
  activate(job);
  save(job);
  log_jobs()->log(q != nullptr && q->retrying ? spdlog::level::debug : spdlog::level::info,
                  "job {} queued again ('{}'): retried after it {}", id, spec.name,
                  state == wire::JOB_FAILED ? "failed" : "was cancelled");
  return job.record.state;
}

void JobManager::tick() {
  const auto now = Clock::now();
  // A cancelled sequence's next slice of frames.
  for (auto& [id, q] : sequences_) {
    if (q.cancelled) cancel_slice(id, q);
  }
  // Only the jobs that may need it: started ones, and those with a storage error (attention_).
  for (auto it = attention_.begin(); it != attention_.end();) {
    ++jobs_visited_;
    auto found = jobs_.find(*it);
    if (found == jobs_.end()) {
      it = attention_.erase(it);
      continue;
    }
    Job& job = found->second;
    tick_job(found->first, job, now);
    const bool needs = (job.active && job.active->started()) || !job.storage_error.empty();
    it = needs ? std::next(it) : attention_.erase(it);
  }
}

void JobManager::tick_job(const std::string& id, Job& job, Clock::time_point now) {
  ActiveJob* a = job.active.get();
  if (!job.storage_error.empty() && now >= job.storage_retry) {
    if (a && a->finishing) {
      const ActiveJob::Finishing f = *a->finishing;
      finish(job, f.state, f.error, f.reason);
    } else if (job.record_unsaved) {
      if (save(job)) {
        job.storage_error.clear();
        if (!a) checkpoints_.forget(id, store_.job_dir(id));
        log_jobs()->info("job {}: its record is on disk again", id);
        note(job.record, "info", "its record is on disk again");  // saved with the next
      }
    } else {
      // An image or checkpoint failure: cleared once a later write succeeds.
      std::string failure = writer_.failure(store_.image_path(id));
      if (failure.empty()) failure = checkpoints_.failure(id);
      if (failure.empty() || !a) {
        job.storage_error.clear();
      } else {
        storage_failed(job, failure);
      }
    }
    if (job.storage_error.empty()) job.storage_backoff = std::chrono::milliseconds{0};
    return;
  }
  if (!a || a->finishing) return;
  if (fail_if_nobody_can_render(job, now)) return;
  // Failures of the writer threads show in the job's status until a later write succeeds.
  std::string failure = writer_.failure(store_.image_path(id));
  if (failure.empty()) failure = checkpoints_.failure(id);
  if (!failure.empty() && job.storage_error.empty()) storage_failed(job, failure);
  const double limit = job.record.spec.stop.time_limit_s;
  if (a->started() && limit > 0 && a->elapsed() >= limit) {
    log_jobs()->info("job {}: time limit of {:g} s reached", id, limit);
    note(job.record, "info", fmt::format("time limit of {:g} s reached", limit));
    finish(job, wire::JOB_DONE, "", StopReason::kTimeLimit);
    return;
  }
  if (a->dirty && now - a->last_write >= image_interval(job)) write_image(job);
  if (a->checkpoint_due && options_.checkpoint_interval.count() > 0 &&
      now - a->last_checkpoint >= checkpoint_interval(job)) {
    checkpoint(job);
  }
}

namespace {

/// `interval`, or the time in which `cost` seconds are `share` of it when that is longer.
JobManager::Clock::duration stretched(JobManager::Clock::duration interval, double cost,
                                      double share) {
  if (share <= 0 || cost <= 0) return interval;
  const auto budget = std::chrono::duration_cast<JobManager::Clock::duration>(
      std::chrono::duration<double>(cost / share));
  return std::max(interval, budget);
}

}  // namespace

JobManager::Clock::duration JobManager::image_interval(const Job& job) const {
  const std::string& id = job.record.spec.id;
  const double cost = job.active->image_seconds + writer_.seconds(store_.image_path(id));
  return stretched(options_.image_interval, cost, options_.write_share);
}

JobManager::Clock::duration JobManager::checkpoint_interval(const Job& job) const {
  const double cost = job.active->checkpoint_seconds + checkpoints_.seconds(job.record.spec.id);
  return stretched(options_.checkpoint_interval, cost, options_.write_share);
}

size_t JobManager::active_jobs() const {
  return static_cast<size_t>(std::count_if(
      jobs_.begin(), jobs_.end(), [](const auto& kv) { return kv.second.active != nullptr; }));
}

}  // namespace rayfarm::master
