// The job lifecycle: making a job active, leasing its units, merging results, counting failures,
// and cancel, remove and retry. Admission, recovery, status and the end of a job have files of
// their own (job_manager.h).
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
  scheduler_.set_priority(id, job.record.priority);
  scheduler_.set_paused(id, job.record.paused);
  if (job.record.paused) a.pause(Clock::now());
  a.planner.take_released();  // handed over below, with every other released unit
  if (a.merger.merged_count() == 0 && !a.planner.gated()) {
    scheduler_.release_all(id, a.grid().size());
    return;
  }
  std::vector<uint64_t> units;
  for (uint64_t unit = 0; unit < a.grid().size(); ++unit) {
    if (a.planner.is_released(unit) && !a.merger.merged(unit)) units.push_back(unit);
  }
  scheduler_.release(id, units);
}

std::optional<wire::WorkUnit> JobManager::next_unit(const WorkerId& worker,
                                                    const std::string& key) {
  const auto now = Clock::now();
  auto ref = scheduler_.lease(worker, now, key);
  if (!ref) {
    const auto straggler = scheduler_.lease_straggler(worker, options_.stragglers, now, key);
    if (!straggler) return std::nullopt;
    ref = straggler->unit;
    log_scheduler()->info(
        "job {} unit {} is a straggler: leased to {} for {:.1f} s, the job's median unit takes "
        "{:.2f} s; also leased to {}, the first result is merged",
        ref->job, ref->unit, name_of(straggler->first), straggler->leased_seconds,
        straggler->median_seconds, name_of(worker));
  }
  Job& job = jobs_.at(ref->job);
  ActiveJob& a = *job.active;
  const JobSpec& s = job.record.spec;
  {
    // The unit's past holders: kept until it merges, the latest few (a unit handed out again and
    // again to reconnecting workers must not grow without bound).
    constexpr size_t kHoldersKept = 8;
    auto& holders = a.lease_history[ref->unit];
    const std::pair<WorkerId, std::string> holder{worker, key};
    if (std::find(holders.begin(), holders.end(), holder) == holders.end()) {
      if (holders.size() >= kHoldersKept) holders.erase(holders.begin());
      holders.push_back(holder);
    }
  }
  if (!a.started()) {
    a.start_time = Clock::now();
    a.last_write = *a.start_time;
    job.record.state = wire::JOB_RUNNING;
    save(job);
    log_jobs()->info("job {} started", s.id);
  }
  const UnitGrid::Unit u = a.grid().unit(ref->unit);
  wire::WorkUnit out;
  out.set_job_id(s.id);
  out.set_unit_id(u.id);
  *out.mutable_tile() = protocol::rect_to_wire(u.rect);
  out.set_sample_begin(u.samples.begin);
  out.set_sample_end(u.samples.end);
  *out.mutable_settings() = protocol::settings_to_wire(s.settings);
  out.set_bundle_hash(s.bundle_hash);
  out.set_scene_path(s.scene_path);
  out.set_pass(u.pass);
  out.set_film_width(s.film.width);  // the job's film, which may override the scene's
  out.set_film_height(s.film.height);
  if (s.frame && !s.frame_file) out.set_frame(*s.frame);  // a list's file is a still
  log_scheduler()->debug("job {} unit {} (pass {}) leased to {}", s.id, u.id, u.pass,
                         name_of(worker));
  return out;
}

MergeOutcome JobManager::on_result(const WorkerId& worker, const wire::UnitResult& result,
                                   const std::string& key) {
  const std::string& id = result.job_id();
  auto it = jobs_.find(id);
  if (it == jobs_.end()) {
    log_merger()->debug("result for unknown job '{}' from {} dropped", protocol::printable(id),
                        name_of(worker));
    return MergeOutcome::kUnleased;  // no job, so nothing was leased
  }
  Job& job = it->second;
  const UnitRef ref{id, result.unit_id()};
  // Lines about dropped results are a peer's to cause: a burst per key, then one a second.
  // (Taken only when a result is dropped: merged results spend nothing.)
  auto level = [&] {
    return log_budget_.take(key.empty() ? worker : key) ? spdlog::level::info
                                                        : spdlog::level::debug;
  };
  if (!job.active) {
    if (job.record.state == wire::JOB_DONE) {
      log_merger()->log(level(), "job {} unit {}: duplicate result from {} dropped (the job is done)",
                        id, result.unit_id(), name_of(worker));
      return MergeOutcome::kDuplicate;
    }
    log_merger()->log(level(), "job {} unit {}: result from {} dropped (the job is {})", id,
                      result.unit_id(), name_of(worker),
                      protocol::job_state_name(job.record.state));
    return MergeOutcome::kRejected;
  }
  ActiveJob& a = *job.active;
  if (a.finishing) {
    log_merger()->log(level(), "job {} unit {}: result from {} dropped (the job's work is done)", id,
                      result.unit_id(), name_of(worker));
    return MergeOutcome::kDuplicate;
  }
  auto reject = [&](const std::string& why) {
    log_merger()->warn("job {} unit {}: result from {} rejected: {}", id, result.unit_id(),
                       name_of(worker), why);
    scheduler_.requeue(ref, worker);
    note_failure(job, worker, key, result.unit_id(), "result rejected: " + why);
    return MergeOutcome::kRejected;
  };
  if (a.merger.merged(result.unit_id())) {
    log_merger()->log(level(), "job {} unit {}: duplicate result from {} dropped (merged before)", id,
                      result.unit_id(), name_of(worker));
    return MergeOutcome::kDuplicate;
  }
  // Only the connection that was leased the unit may return it: another peer's result, even with
  // a valid worker key, is dropped and counts against nobody (it cannot fail the job either).
  const auto history = a.lease_history.find(result.unit_id());
  if (history == a.lease_history.end() ||
      std::find(history->second.begin(), history->second.end(), std::pair{worker, key}) ==
          history->second.end()) {
    log_merger()->debug("job {} unit {}: result from {} dropped: the unit was never leased to it",
                        id, result.unit_id(), name_of(worker));
    return MergeOutcome::kUnleased;
  }
  if (!a.planner.is_released(result.unit_id())) {
    return reject("the unit was never handed out (the job's stopping rules have not released it)");
  }
  TileResult tile;
  std::string why;
  try {
    // The tile sizes the decoding of the sums (a packed value may take one byte): it must be the
    // unit's before anything is decoded, or a small message claiming a huge tile would make the
    // master allocate many times its size.
    if (!a.merger.covers(result.unit_id(), protocol::rect_from_wire(result.tile()),
                         SampleRange{result.sample_begin(), result.sample_end()}, &why)) {
      return reject(why);
    }
    tile = protocol::result_from_wire(result);
  } catch (const protocol::ProtocolError& e) {
    return reject(e.what());
  }
  MergeOutcome outcome;
  try {
    outcome = a.merger.add(result.unit_id(), tile, &why);  // the first allocates the film
  } catch (const std::bad_alloc&) {
    // The master cannot hold the job's image: the job fails, saying so, instead of leasing the
    // unit again and again.
    log_merger()->error("job {}: no memory for its {}x{} film", id, a.grid().film().width,
                        a.grid().film().height);
    finish(job, wire::JOB_FAILED,
           fmt::format("the master has no memory for the job's {}x{} image", a.grid().film().width,
                       a.grid().film().height),
           StopReason::kFailed);
    return MergeOutcome::kRejected;
  }
  if (outcome == MergeOutcome::kRejected) return reject(why);
  if (outcome == MergeOutcome::kDuplicate) return outcome;  // checked above; kept for clarity

  scheduler_.complete(ref, worker);
  a.lease_history.erase(result.unit_id());
  a.dirty = true;
  a.checkpoint_due = true;
  a.contributors[worker] = Clock::now();
  log_merger()->debug("job {} unit {} merged from {} ({:.3f} s render)", id, result.unit_id(),
                      name_of(worker), result.render_seconds());
  a.tracker.update_tile(a.merger.film(), a.grid().tile_of(result.unit_id()));
  PassPlanner& planner = a.planner;
  planner.on_merged(result.unit_id(), a.merger.merged_units(), a.merger.film(),
                    &a.tracker.estimate());
  scheduler_.release(id, planner.take_released());
  if (planner.rounds_complete(a.merger.merged_units()) > a.rounds_recorded) on_round_done(job);
  if (planner.finished()) finish(job, wire::JOB_DONE, "", planner.reason());
  return outcome;
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
  if (rounds_before == 0 || now - a.last_write >= options_.image_interval) write_image(job);
  if (options_.checkpoint_interval.count() == 0 ||
      now - a.last_checkpoint >= options_.checkpoint_interval) {
    checkpoint(job);
  }
}

bool JobManager::on_unit_failed(const WorkerId& worker, const wire::UnitFailed& failed,
                                const std::string& key) {
  auto it = jobs_.find(failed.job_id());
  if (it == jobs_.end() || !it->second.active) return false;
  Job& job = it->second;
  const UnitRef ref{failed.job_id(), failed.unit_id()};
  const std::string reason = protocol::printable(failed.reason(), 500);
  if (!scheduler_.holds(ref, worker)) {
    log_jobs()->debug("job {} unit {}: failure report from {} ignored: it does not hold the unit",
                      ref.job, ref.unit, name_of(worker));
    return false;
  }
  log_jobs()->warn("job {} unit {} failed on {}: {}", ref.job, ref.unit, name_of(worker), reason);
  scheduler_.requeue(ref, worker);
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

size_t JobManager::release_worker(const WorkerId& worker) {
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
  return units.size();
}

std::optional<wire::JobState> JobManager::cancel(const std::string& id) {
  if (const auto* frames = sequence_frames(id)) return cancel_sequence(*frames);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return std::nullopt;
  if (it->second.active) finish(it->second, wire::JOB_CANCELLED, "cancelled by a client");
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
  // A frame's bundle is its sequence's, which remove_sequence() rebinds once it is gone.
  if (!frame) rebind_bundle(hash, id);
  log_jobs()->info("job {} removed with its files", id);
}

wire::JobState JobManager::retry(const std::string& id) {
  if (const auto* frames = sequence_frames(id)) return retry_sequence(id, *frames);
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
  if (!store_.load_bundle(JobStore::bundle_holder(job.record.spec))) {
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
  r = JobRecord{};
  r.spec = spec;
  r.priority = priority;  // a retried job keeps its place among the others, and runs
  job.storage_error.clear();
  job.record_unsaved = false;
  activate(job);
  save(job);
  log_jobs()->info("job {} queued again ('{}'): retried after it {}", id, spec.name,
                   state == wire::JOB_FAILED ? "failed" : "was cancelled");
  return job.record.state;
}

void JobManager::tick() {
  const auto now = Clock::now();
  for (auto& [id, job] : jobs_) {
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
      continue;
    }
    if (!a || a->finishing) continue;
    if (fail_if_nobody_can_render(job, now)) continue;
    // Failures of the writer threads show in the job's status until a later write succeeds.
    std::string failure = writer_.failure(store_.image_path(id));
    if (failure.empty()) failure = checkpoints_.failure(id);
    if (!failure.empty() && job.storage_error.empty()) storage_failed(job, failure);
    const double limit = job.record.spec.stop.time_limit_s;
    if (a->started() && limit > 0 && a->elapsed() >= limit) {
      log_jobs()->info("job {}: time limit of {:g} s reached", id, limit);
      finish(job, wire::JOB_DONE, "", StopReason::kTimeLimit);
      continue;
    }
    if (a->dirty && now - a->last_write >= options_.image_interval) write_image(job);
    if (a->checkpoint_due && options_.checkpoint_interval.count() > 0 &&
        now - a->last_checkpoint >= options_.checkpoint_interval) {
      checkpoint(job);
    }
  }
}

size_t JobManager::active_jobs() const {
  return static_cast<size_t>(std::count_if(
      jobs_.begin(), jobs_.end(), [](const auto& kv) { return kv.second.active != nullptr; }));
}

}  // namespace rayfarm::master
