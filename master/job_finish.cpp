// How a job ends: its final record and image on disk, and what happens while they cannot be
// written (the job stays running with its checkpoints and is retried with back-off).
#include <algorithm>

#include "common/image/film_output.h"
#include "common/scene/motion.h"
#include "common/util/check.h"
#include "master/job_manager.h"
#include "master/job_text.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
using namespace detail;

void JobManager::finish(Job& job, wire::JobState state, const std::string& error,
                        StopReason reason) {
  RAYFARM_CHECK(job.active != nullptr, "finishing a job that is not active");
  ActiveJob& a = *job.active;
  const JobSpec& s = job.record.spec;
  if (reason == StopReason::kRunning) {
    reason = state == wire::JOB_CANCELLED ? StopReason::kCancelled
             : state == wire::JOB_FAILED  ? StopReason::kFailed
                                          : StopReason::kSpp;
  }
  // The last row of the error record describes the final image.
  if (a.merger.samples_merged() > a.samples_recorded) {
    a.record_row();
    a.dirty = true;
  }
  const bool write_final_image = state == wire::JOB_DONE || a.dirty || a.finishing.has_value();
  // The record as it will be once the job has ended.
  JobRecord final_record = job.record;
  JobRecord& r = final_record;
  r.stop_reason = stop_reason_name(reason);
  r.elapsed_seconds = a.finishing ? a.finishing->elapsed : a.elapsed();
  r.state = state;
  r.finished_unix_ms = wall_ms();
  r.paused = false;  // an ended job is not paused, whatever it was
  r.error = error;
  r.units_done = a.merger.merged_count();
  r.spp_min = a.merger.min_spp();
  // Passes every pixel has (a converged tile skips the later ones), as the live status counts.
  r.passes_done = a.grid().passes_within(r.spp_min);
  r.spp_mean =
      static_cast<double>(a.merger.samples_merged()) / (double(s.film.width) * s.film.height);
  r.tiles_converged = a.planner.tiles_converged();
  if (!a.rows.empty()) {
    r.est_rel_mse = a.rows.back().est_rel_mse;
    if (a.rows.back().ref_rel_mse) r.ref_rel_mse = *a.rows.back().ref_rel_mse;
  }
  {
    // How it ended, in its log, and who rendered it.
    const double seconds = r.elapsed_seconds;
    std::string by;
    size_t named = 0;
    for (const auto& [worker, share] : a.book.shares()) {
      if (share.units_done == 0) continue;
      if (named++ == 8) {
        by += ", ...";
        break;
      }
      by += fmt::format("{}{} ({} unit{})", by.empty() ? "" : ", ", worker, share.units_done,
                        share.units_done == 1 ? "" : "s");
    }
    // final_record is a fresh copy of the job's at each try of the final writes: noted once.
    if (state == wire::JOB_DONE) {
      note(r, "info",
           fmt::format("done ({}): {:.1f} spp mean in {:.2f} s{}", r.stop_reason, r.spp_mean,
                       seconds, by.empty() ? "" : "; rendered by " + by),
           /*routine=*/true);
    } else if (state == wire::JOB_CANCELLED) {
      note(r, "info", fmt::format("{} after {:.2f} s at {} spp", error, seconds, r.spp_min),
           /*routine=*/true);
    } else {
      note(r, "error", fmt::format("failed after {:.2f} s: {}", seconds, error));
    }
  }
  scheduler_.remove_job(s.id);  // no more units either way
  if (state == wire::JOB_DONE) {
    // Done means on disk: the final image and the record. Until both are, the job stays running
    // with its checkpoints, and tick() tries again.
    const std::string problem = store_final(job, final_record, write_final_image);
    if (!problem.empty()) {
      if (!a.finishing) {
        a.finishing = ActiveJob::Finishing{state, error, reason, final_record.elapsed_seconds};
        checkpoint(job);  // the merged state, in case the master stops before the disk recovers
      }
      storage_failed(job, problem);
      return;
    }
  } else if (write_final_image) {
    write_image(job, /*wait=*/true);  // a cancelled or failed job keeps what it rendered
  }
  const uint64_t samples = a.merger.samples_merged();
  const std::string error_summary =
      a.rows.empty()
          ? ""
          : fmt::format(", estimated relMSE {:.3g}{}", a.rows.back().est_rel_mse,
                        a.rows.back().ref_rel_mse
                            ? fmt::format(", measured {:.3g}", *a.rows.back().ref_rel_mse)
                            : "");
  const bool record_saved = state == wire::JOB_DONE;
  job.record = std::move(final_record);
  job.active.reset();  // `a` is gone from here on
  // A sequence's cancel is logged once, as the sequence's.
  const Sequence* q = sequence_of(s);
  const bool sequence_cancelled = q != nullptr && q->cancelled;
  if (!s.sequence.empty()) frame_ended(s.sequence);
  // The record says how the job ended; its checkpoints are of no use any more once it is on
  // disk (until then they are what a restarted master resumes from).
  if (record_saved || save(job)) {
    job.storage_error.clear();
    checkpoints_.forget(s.id, store_.job_dir(s.id));
  }
  // A finished frame joins its sequence's contact sheet (and, the last one, makes its movie).
  if (state == wire::JOB_DONE && !s.sequence.empty() && !recovering_) {
    update_previews(s.sequence);
  }
  const double seconds = job.record.elapsed_seconds;
  if (state == wire::JOB_DONE) {
    log_jobs()->info("job {} done ({}): '{}' {}x{}, {:.1f} spp mean in {:.2f} s ({}){}; image {}",
                     s.id, job.record.stop_reason, s.name, s.film.width, s.film.height,
                     static_cast<double>(samples) / (double(s.film.width) * s.film.height), seconds,
                     human_rate(seconds > 0 ? samples / seconds : 0.0), error_summary,
                     (store_.job_dir(s.id) / "image.exr").string());
  } else if (state == wire::JOB_CANCELLED) {
    log_jobs()->log(sequence_cancelled ? spdlog::level::debug : spdlog::level::info,
                    "job {} cancelled after {:.2f} s at {} spp", s.id, seconds,
                    job.record.spp_min);
  } else {
    log_jobs()->error("job {} failed after {:.2f} s: {}", s.id, seconds, error);
  }
}

std::string JobManager::store_final(Job& job, const JobRecord& final_record, bool image) {
  const std::string& id = job.record.spec.id;
  if (image) {
    write_image(job, /*wait=*/true);
    const std::string failure = writer_.failure(store_.image_path(id));
    if (!failure.empty()) return "cannot write the final image: " + failure;
  }
  try {
    store_.save_record(final_record);
    store_.sync_job_dir(id);  // the renames too, before the checkpoints go
  } catch (const std::exception& e) {
    return std::string("cannot save the job's record: ") + e.what();
  }
  job.record_unsaved = false;
  return "";
}

void JobManager::storage_failed(Job& job, const std::string& what) {
  using std::chrono::milliseconds;
  const bool first = job.storage_error.empty();
  job.storage_backoff =
      first ? milliseconds{1000} : std::min(job.storage_backoff * 2, milliseconds{30000});
  job.storage_retry = Clock::now() + job.storage_backoff;
  job.storage_error = what;
  attention_.insert(job.record.spec.id);  // tick() tries again
  if (first) note(job.record, "error", what + "; the master tries again with back-off");
  log_jobs()->error("job {}: {}{}; trying again in {:.0f} s", job.record.spec.id, what,
                    job.active && job.active->finishing
                        ? " (its work is done: it stays running, with its checkpoints, "
                          "until its final image and record are on disk)"
                        : "",
                    job.storage_backoff.count() / 1000.0);
}

void JobManager::write_image(Job& job, bool wait) {
  const auto start = Clock::now();
  const JobSpec& s = job.record.spec;
  // The same attributes as `rayfarm render`, plus the job's own.
  std::map<std::string, std::string> attributes{
      {"rayfarm:integrator", integrator_name(s.settings.integrator)},
      {"rayfarm:seed", std::to_string(s.settings.seed)},
      {"rayfarm:max_depth", depth_name(s.settings.max_depth)},
      {"rayfarm:sampler", sampler_name(s.settings.sampler)},
      {"rayfarm:roulette", roulette_name(s.settings.roulette)},
      {"rayfarm:roulette_depth", std::to_string(s.settings.roulette_depth)},
      {"rayfarm:scene", fs::path(s.scene_path).filename().string()},
      {"rayfarm:job", s.id},
      {"rayfarm:spp_target", std::to_string(s.settings.spp)}};
  if (s.settings.clamp > 0) attributes["rayfarm:clamp"] = fmt::format("{:g}", s.settings.clamp);
  if (s.frame) attributes["rayfarm:frame"] = std::to_string(*s.frame);
  if (s.settings.shutter_is_open()) attributes["rayfarm:shutter"] = shutter_attribute(s.settings);
  // The same pixels as `rayfarm render` (film_to_image), written on the writer's thread.
  ImageWriter::ErrorRecord record;
  record.rows = job.active->rows;
  record.title =
      fmt::format("job {} '{}' ({})", s.id, s.name, integrator_name(s.settings.integrator));
  writer_.submit(store_.image_path(s.id), film_to_image(job.active->merger.film(), attributes),
                 std::move(record));
  job.active->image_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  if (wait) writer_.flush();
  job.active->dirty = false;
  job.active->last_write = Clock::now();
}

bool JobManager::save(Job& job) {
  if (job.record.unreadable) return true;  // its job.json stays as it is, for a look
  try {
    store_.save_record(job.record);
    job.log_saved = job.record.log.version;
  } catch (const std::exception& e) {
    job.record_unsaved = true;
    storage_failed(job, std::string("cannot save the job's record: ") + e.what());
    return false;
  }
  job.record_unsaved = false;
  return true;
}

}  // namespace rayfarm::master
