// Leases and results: the units a worker gets (one, or a run of one tile's passes sized by time,
// scheduler.h) and the merge of what it sends back, checked against what it was given.
#include <algorithm>
#include <cmath>

#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "master/job_manager.h"
#include "master/job_text.h"

namespace rayfarm::master {
namespace protocol = rayfarm::protocol;
using namespace detail;

std::optional<wire::WorkUnit> JobManager::next_unit(const WorkerId& worker,
                                                    const std::string& key) {
  const auto now = Clock::now();
  auto lease = scheduler_.lease_run(worker, options_.runs, now, key);
  if (!lease) {
    const auto straggler = scheduler_.lease_straggler(worker, options_.stragglers, now, key);
    if (!straggler) return std::nullopt;
    lease = Lease{straggler->unit.job, straggler->units};
    note(jobs_.at(lease->job).record, "info",
         fmt::format("unit {} leased a second time, to {}: {} has held it for {:.1f} s, the "
                     "job's median unit takes {:.2f} s; the first result is merged",
                     lease->units.front(), name_of(worker), name_of(straggler->first),
                     straggler->leased_seconds, straggler->median_seconds));
    log_scheduler()->info(
        "job {} unit {} is a straggler: leased to {} for {:.1f} s ({} unit{}), the job's median "
        "unit takes {:.2f} s; also leased to {}, the first result is merged",
        lease->job, lease->units.front(), name_of(straggler->first), straggler->leased_seconds,
        lease->units.size(), lease->units.size() == 1 ? "" : "s", straggler->median_seconds,
        name_of(worker));
  }
  Job& job = jobs_.at(lease->job);
  ActiveJob& a = *job.active;
  const JobSpec& s = job.record.spec;
  for (const uint64_t unit : lease->units) {
    a.book.leased(unit);
    // The unit's past holders: kept until it merges, the latest few (a unit handed out again and
    // again to reconnecting workers must not grow without bound).
    constexpr size_t kHoldersKept = 8;
    auto& holders = a.lease_history[unit];
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
    job.record.started_unix_ms = wall_ms();
    note(job.record, "info", "started: its first unit went to " + name_of(worker),
         /*routine=*/true);
    attention_.insert(s.id);  // tick() looks after it from now on
    save(job);
    log_jobs()->info("job {} started", s.id);
  }
  sequence_started(s, now);
  const UnitGrid::Unit u = a.grid().unit(lease->units.front());
  const auto count = static_cast<uint32_t>(lease->units.size());
  const SampleRange samples = a.grid().run_samples(u.id, count);
  wire::WorkUnit out;
  out.set_job_id(s.id);
  out.set_unit_id(u.id);
  *out.mutable_tile() = protocol::rect_to_wire(u.rect);
  out.set_sample_begin(samples.begin);
  out.set_sample_end(samples.end);
  *out.mutable_settings() = protocol::settings_to_wire(s.settings);
  out.set_bundle_hash(s.bundle_hash);
  out.set_scene_path(s.scene_path);
  out.set_pass(u.pass);
  out.set_film_width(s.film.width);  // the job's film, which may override the scene's
  out.set_film_height(s.film.height);
  if (s.frame && !s.frame_file) out.set_frame(*s.frame);  // a list's file is a still
  log_scheduler()->debug("job {} unit {} ({}) leased to {}", s.id, u.id,
                         count == 1 ? fmt::format("pass {}", u.pass)
                                    : fmt::format("passes {}-{}", u.pass, u.pass + count - 1),
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
  // Lines about dropped or rejected results are a peer's to cause: each within its budget per
  // key (log_budget.h), taken only when a result is dropped (merged results spend nothing).
  auto note = [&](PeerLog kind, spdlog::level::level_enum at, const std::string& text) {
    const LogBudget::Verdict verdict =
        log_budget_.take(kind, key.empty() ? "connection " + worker : "key " + key);
    log_merger()->log(verdict.log ? at : spdlog::level::trace, "{}{}", text, verdict.suffix());
  };
  if (!job.active) {
    if (job.record.state == wire::JOB_DONE) {
      note(PeerLog::kResultDropped, spdlog::level::info,
           fmt::format("job {} unit {}: duplicate result from {} dropped (the job is done)", id,
                       result.unit_id(), name_of(worker)));
      return MergeOutcome::kDuplicate;
    }
    // A cancelled or failed job's units still out come back late: routine, not a wrong result.
    note(PeerLog::kResultDropped, spdlog::level::info,
         fmt::format("job {} unit {}: result from {} dropped (the job is {})", id,
                     result.unit_id(), name_of(worker),
                     protocol::job_state_name(job.record.state)));
    return MergeOutcome::kDiscarded;
  }
  ActiveJob& a = *job.active;
  if (a.finishing) {
    note(PeerLog::kResultDropped, spdlog::level::info,
         fmt::format("job {} unit {}: result from {} dropped (the job's work is done)", id,
                     result.unit_id(), name_of(worker)));
    return MergeOutcome::kDuplicate;
  }
  // The worker's lease the result answers (the units it covers, when the worker holds it now).
  const std::vector<uint64_t> lease = scheduler_.lease_of(ref, worker);
  auto requeue_lease = [&] {
    for (const uint64_t unit : lease) scheduler_.requeue(UnitRef{id, unit}, worker);
  };
  auto reject = [&](const std::string& why) {
    note(PeerLog::kResultRejected, spdlog::level::warn,
         fmt::format("job {} unit {}: result from {} rejected: {}", id, result.unit_id(),
                     name_of(worker), why));
    requeue_lease();
    a.book.failed(result.unit_id(), name_of(worker), "result rejected: " + why);
    JobManager::note(job.record, "warning",
                     fmt::format("a result of unit {} from {} was rejected: {}", result.unit_id(),
                                 name_of(worker), why));
    note_failure(job, worker, key, result.unit_id(), "result rejected: " + why);
    return MergeOutcome::kRejected;
  };
  // The units the result covers: the run of its tile's passes its samples span (one unit, or
  // none that exists: covers() below names the mismatch).
  const SampleRange samples{result.sample_begin(), result.sample_end()};
  const uint32_t run = std::max(a.grid().run_covering(result.unit_id(), samples), 1u);
  std::vector<uint64_t> units;
  for (uint32_t k = 0; k < run; ++k) units.push_back(result.unit_id() + k * a.grid().tile_count());
  const auto merged_before =
      std::count_if(units.begin(), units.end(), [&](uint64_t u) { return a.merger.merged(u); });
  if (merged_before > 0) {
    note(PeerLog::kResultDropped, spdlog::level::info,
         fmt::format("job {} unit {}: duplicate result from {} dropped (merged before{})", id,
                     result.unit_id(), name_of(worker),
                     merged_before == static_cast<long>(run)
                         ? ""
                         : fmt::format(": {} of its {} units", merged_before, run)));
    // The sums cannot be split: the lease's units not merged yet go back to the queue.
    requeue_lease();
    return MergeOutcome::kDuplicate;
  }
  // Only the connection that was leased a unit may return it: another peer's result, even with
  // a valid worker key, is dropped and counts against nobody (it cannot fail the job either).
  for (const uint64_t unit : units) {
    const auto history = a.lease_history.find(unit);
    if (history == a.lease_history.end() ||
        std::find(history->second.begin(), history->second.end(), std::pair{worker, key}) ==
            history->second.end()) {
      log_merger()->debug("job {} unit {}: result from {} dropped: unit {} was never leased to it",
                          id, result.unit_id(), name_of(worker), unit);
      return MergeOutcome::kUnleased;
    }
    if (!a.planner.is_released(unit)) {
      return reject(fmt::format(
          "unit {} was never handed out (the job's stopping rules have not released it)", unit));
    }
  }
  TileResult tile;
  std::string why;
  try {
    // The tile sizes the decoding of the sums (a packed value may take one byte): it must be the
    // unit's before anything is decoded, or a small message claiming a huge tile would make the
    // master allocate many times its size.
    if (!a.merger.covers(result.unit_id(), protocol::rect_from_wire(result.tile()), samples, &why,
                         run)) {
      return reject(why);
    }
    tile = protocol::result_from_wire(result);
  } catch (const protocol::ProtocolError& e) {
    return reject(e.what());
  }
  MergeOutcome outcome;
  try {
    outcome = a.merger.add(result.unit_id(), tile, &why, run);  // the first allocates the film
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

  const auto now = Clock::now();
  for (const uint64_t unit : units) {
    scheduler_.complete(UnitRef{id, unit}, worker, now);
    a.lease_history.erase(unit);
  }
  // A result answers its whole lease: what it left out goes back to the queue.
  for (const uint64_t unit : lease) {
    if (!a.merger.merged(unit)) scheduler_.requeue(UnitRef{id, unit}, worker);
  }
  // The worker's own figure, for its share in the job's detail view: bounded, never NaN.
  const double render = result.render_seconds();
  a.book.merged(result.unit_id(), run, a.grid().tile_count(), name_of(worker),
                std::isfinite(render) ? std::clamp(render, 0.0, 86400.0) : 0.0);
  a.dirty = true;
  a.checkpoint_due = true;
  a.contributors[worker] = now;
  log_merger()->debug("job {} unit {}{} merged from {} ({:.3f} s render)", id, result.unit_id(),
                      run == 1 ? "" : fmt::format(" and the next {} of its tile", run - 1),
                      name_of(worker), result.render_seconds());
  a.tracker.update_tile(a.merger.film(), a.grid().tile_of(result.unit_id()));
  PassPlanner& planner = a.planner;
  // The planner decides once the tile has every released pass merged, so it hears of the run's
  // last unit only: it reads the film then, with all of them in it, as it would one by one.
  planner.on_merged(units.back(), a.merger.merged_units(), a.merger.film(), &a.tracker.estimate());
  scheduler_.release(id, planner.take_released());
  if (planner.rounds_complete(a.merger.merged_units()) > a.rounds_recorded) on_round_done(job);
  if (planner.finished()) finish(job, wire::JOB_DONE, "", planner.reason());
  return outcome;
}

}  // namespace rayfarm::master
