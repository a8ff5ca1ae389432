// Sequences: a sequence's frames are jobs of their own ("j0007.0012", each with its record,
// checkpoints, image and error record), and the sequence ("j0007") is what its client submitted
// and acts on. Its priority, pause and cancellation are the sequence's, set once (the scheduler's
// group, and sequence.json), so that changing them costs the same whatever its length; a cancel
// ends its frames a slice per tick(). Its status sums its frames'. docs/farm.md, "Frame
// sequences".
#include <algorithm>

#include "common/limits.h"
#include "common/protocol/convert.h"
#include "master/job_manager.h"
#include "master/job_text.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
using namespace detail;

namespace {

/// The sequence's name: its frames' names without their " frame N".
std::string sequence_name(const JobSpec& frame) {
  const std::string suffix = " frame " + std::to_string(frame.frame.value_or(0));
  const std::string& name = frame.name;
  if (name.size() > suffix.size() &&
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
    return name.substr(0, name.size() - suffix.size());
  }
  return name;
}

}  // namespace

int64_t JobManager::wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

const std::vector<std::string>* JobManager::sequence_frames(const std::string& id) const {
  auto it = sequences_.find(id);
  if (it == sequences_.end()) return nullptr;
  // A sequence none of whose frames is left (a removal cut short) is unknown, as it would be
  // after a restart.
  for (const std::string& f : it->second.frames) {
    if (jobs_.count(f)) return &it->second.frames;
  }
  return nullptr;
}

JobManager::Sequence* JobManager::sequence_of(const JobSpec& spec) {
  if (spec.sequence.empty()) return nullptr;
  auto it = sequences_.find(spec.sequence);
  return it == sequences_.end() ? nullptr : &it->second;
}

const JobManager::Sequence* JobManager::sequence_of(const JobSpec& spec) const {
  if (spec.sequence.empty()) return nullptr;
  auto it = sequences_.find(spec.sequence);
  return it == sequences_.end() ? nullptr : &it->second;
}

void JobManager::save_sequence(const std::string& id, const Sequence& q) {
  SequenceRecord r;
  r.id = id;
  r.frames = q.frames.size();
  r.fps = store_.sequence_fps(id);
  r.has_state = true;
  r.priority = q.priority;
  r.paused = q.paused;
  r.cancelled_unix_ms = q.cancelled_unix_ms;
  r.elapsed_seconds = q.elapsed(Clock::now());
  try {
    store_.save_sequence(r);
  } catch (const std::exception& e) {
    // The state holds in memory; a restart before the next save finds the previous one.
    log_jobs()->error("sequence {}: cannot save its state: {}", id, e.what());
  }
}

void JobManager::sequence_started(const JobSpec& frame, Clock::time_point now) {
  Sequence* q = sequence_of(frame);
  if (q != nullptr && !q->running_since && !q->paused && !q->cancelled) q->running_since = now;
}

void JobManager::frame_ended(const std::string& id) {
  auto it = sequences_.find(id);
  if (it == sequences_.end()) return;
  Sequence& q = it->second;
  if (q.active > 0) --q.active;
  if (q.active > 0) return;
  // Its last frame: the clock stops, and what the sequence was is kept.
  q.elapsed_before = q.elapsed(Clock::now());
  q.running_since.reset();
  if (!recovering_) save_sequence(id, q);
  if (q.cancelled) log_jobs()->info("sequence {}: every frame cancelled has ended", id);
  q.cancelled = false;  // nothing left to end
}

void JobManager::pause_frames(const std::string& id, bool paused, Clock::time_point now) {
  // Only a started frame has a clock to stop, and every one is in attention_.
  for (const std::string& f : attention_) {
    ++jobs_visited_;
    auto it = jobs_.find(f);
    if (it == jobs_.end() || !it->second.active || it->second.record.spec.sequence != id) continue;
    Job& job = it->second;
    if (paused) {
      job.active->pause(now);
    } else if (!job.record.paused) {
      job.active->resume(now);
    }
  }
}

wire::JobState JobManager::cancel_sequence(const std::string& id) {
  Sequence& q = sequences_.at(id);
  if (q.active == 0) return sequence_state(q);
  if (!q.cancelled) {
    q.cancelled = true;
    q.cancel_next = 0;
    // After every frame queued so far, even within the same millisecond: a restart tells the
    // frames this cancel ended from those a later retry queued.
    q.cancelled_unix_ms = std::max(wall_ms(), q.queued_unix_ms + 1);
    // Its pause ends with it: a retry later queues frames that run.
    q.paused = false;
    q.paused_alone.clear();
    q.elapsed_before = q.elapsed(Clock::now());
    q.running_since.reset();
    scheduler_.set_group(id, q.priority, /*paused=*/true);  // no frame gets a unit again
    save_sequence(id, q);
    log_jobs()->info("sequence {} cancelled by a client: its {} frames queued or running end {} "
                     "at a time",
                     id, q.active, kCancelSlice);
    cancel_slice(id, q);  // a short sequence ends here and now
  }
  return wire::JOB_CANCELLED;
}

void JobManager::cancel_slice(const std::string& id, Sequence& q) {
  size_t visited = 0, started = 0;
  while (q.cancel_next < q.frames.size() && visited < kCancelSlice &&
         started < kCancelStartedSlice) {
    ++visited;
    ++jobs_visited_;
    auto it = jobs_.find(q.frames[q.cancel_next++]);
    if (it == jobs_.end() || !it->second.active || it->second.active->finishing) continue;
    Job& job = it->second;
    if (job.active->started()) {
      // Its image keeps what was merged: written, with its record, as any cancelled job's.
      ++started;
      finish(job, wire::JOB_CANCELLED, "cancelled by a client");
      continue;
    }
    // Nothing rendered, nothing to write: its record on disk still says queued, and the
    // sequence's, saved as cancelled, says what it is (a restart reads them so).
    scheduler_.remove_job(job.record.spec.id);
    JobRecord& r = job.record;
    r.state = wire::JOB_CANCELLED;
    r.error = "cancelled by a client";
    r.stop_reason = stop_reason_name(StopReason::kCancelled);
    r.paused = false;
    r.finished_unix_ms = q.cancelled_unix_ms;
    job.active.reset();
    frame_ended(id);
  }
  if (q.cancel_next == q.frames.size()) q.cancelled = false;  // every frame looked at: done
}

const JobRecord* JobManager::change_sequence(const std::string& id,
                                             std::optional<int32_t> priority,
                                             std::optional<bool> paused) {
  Sequence& q = sequences_.at(id);
  if (q.cancelled || q.active == 0) {
    throw JobRejected(fmt::format(
        "sequence {} is {}: only a queued or running sequence can be paused, resumed or given a "
        "priority",
        id, protocol::job_state_name(sequence_state(q))));
  }
  if (priority && (*priority < kMinPriority || *priority > kMaxPriority)) {
    throw JobRejected(fmt::format("priority {} is out of range ({} to {})", *priority, kMinPriority,
                                  kMaxPriority));
  }
  const auto now = Clock::now();
  std::string what;
  if (priority && *priority != q.priority) {
    what = fmt::format("priority {} (was {})", *priority, q.priority);
    q.priority = *priority;
  }
  const bool was_paused = q.paused;
  if (paused) {
    q.paused = *paused;
    if (q.paused && !was_paused) {
      q.elapsed_before = q.elapsed(now);
      q.running_since.reset();
    }
  }
  // Resuming the sequence resumes the frames paused alone too, also when the sequence itself
  // was not paused (a sequence stored before its pause was its own kept it in its frames); the
  // sequence is no longer paused here, so each frame's clock runs again.
  if (paused && !*paused && !q.paused_alone.empty()) {
    const size_t alone = q.paused_alone.size();
    for (const std::string& f : std::vector<std::string>(q.paused_alone.begin(),
                                                         q.paused_alone.end())) {
      ++jobs_visited_;
      auto it = jobs_.find(f);
      if (it != jobs_.end() && it->second.active && !it->second.active->finishing) {
        change_one(f, std::nullopt, false);
      }
    }
    q.paused_alone.clear();
    what += fmt::format("{}{} frame{} paused alone resumed", what.empty() ? "" : ", ", alone,
                        alone == 1 ? "" : "s");
  }
  if (paused && q.paused != was_paused) {
    pause_frames(id, q.paused, now);
    what += fmt::format("{}{}", what.empty() ? "" : ", ", q.paused ? "paused" : "resumed");
  }
  if (!what.empty()) {
    scheduler_.set_group(id, q.priority, q.paused);
    save_sequence(id, q);
    log_jobs()->info("sequence {}: {} ({} frames queued or running)", id, what, q.active);
  }
  q.reply = JobRecord{};
  q.reply.spec.id = id;
  q.reply.spec.owner = jobs_.at(q.frames.front()).record.spec.owner;
  q.reply.state = q.running_since || q.elapsed_before > 0 ? wire::JOB_RUNNING : wire::JOB_QUEUED;
  q.reply.priority = q.priority;
  q.reply.paused = q.paused;
  return &q.reply;
}

void JobManager::remove_sequence(const std::string& id) {
  const Sequence& q = sequences_.at(id);
  if (q.active > 0) {
    throw JobRejected(
        q.cancelled
            ? fmt::format("sequence {} is being cancelled ({} frames left to end): remove it in a "
                          "moment",
                          id, q.active)
            : fmt::format("sequence {} has {} frames queued or running: cancel it first", id,
                          q.active));
  }
  const std::vector<std::string> frames = q.frames;
  previews_.forget(id);  // nothing reads the frames' images any more
  std::string hash;
  for (const std::string& f : frames) {
    if (!jobs_.count(f)) continue;
    hash = jobs_.at(f).record.spec.bundle_hash;
    remove_job(f);
  }
  // The sequence's own folder (its bundle, its previews) goes last: until then a frame may still
  // need it.
  std::error_code ec;
  fs::remove_all(store_.job_dir(id), ec);
  if (ec) {
    throw JobRejected(
        fmt::format("cannot remove {}: {}", store_.job_dir(id).string(), ec.message()));
  }
  sequences_.erase(id);
  rebind_bundle(hash, id);
  log_jobs()->info("sequence {} removed with its {} frames", id, frames.size());
}

uint64_t JobManager::retry_count(const std::string& id) const {
  const auto* frames = sequence_frames(id);
  if (frames == nullptr) return jobs_.count(id) ? 1 : 0;
  uint64_t n = 0;
  for (const std::string& f : *frames) {
    auto it = jobs_.find(f);
    if (it == jobs_.end() || it->second.record.unreadable) continue;
    const wire::JobState s = it->second.record.state;
    n += s == wire::JOB_FAILED || s == wire::JOB_CANCELLED;
  }
  return n;
}

wire::JobState JobManager::retry_sequence(const std::string& id, const std::string& by) {
  Sequence& q = sequences_.at(id);
  if (q.cancelled) {
    throw JobRejected(fmt::format(
        "sequence {} is being cancelled ({} frames left to end): retry it in a moment", id,
        q.active));
  }
  if (!store_.load_bundle(id)) {
    throw JobRejected("sequence " + id +
                      " cannot be retried: its bundle is missing from the data dir");
  }
  size_t retried = 0;
  q.retrying = true;  // checked once above; its frames log at debug level
  try {
    for (const std::string& f : q.frames) {
      auto it = jobs_.find(f);
      if (it == jobs_.end() || it->second.record.unreadable) continue;
      const wire::JobState s = it->second.record.state;
      if (s == wire::JOB_FAILED || s == wire::JOB_CANCELLED) {
        retry(f, by);
        ++retried;
      }
    }
  } catch (...) {
    q.retrying = false;
    throw;
  }
  q.retrying = false;
  if (retried == 0) {
    throw JobRejected(fmt::format("sequence {} has no failed or cancelled frame to retry", id));
  }
  save_sequence(id, q);
  log_jobs()->info("sequence {}: {} failed or cancelled frames queued again", id, retried);
  return sequence_state(q);
}

wire::JobState JobManager::sequence_state(const Sequence& q) const {
  bool active = false, running = false, done = false, failed = false, all_done = true;
  for (const std::string& f : q.frames) {
    auto it = jobs_.find(f);
    wire::JobState s = it == jobs_.end() ? wire::JOB_FAILED : it->second.record.state;
    if (q.cancelled && is_active_state(s)) s = wire::JOB_CANCELLED;  // being ended
    active = active || is_active_state(s);
    running = running || s == wire::JOB_RUNNING;
    done = done || s == wire::JOB_DONE;
    failed = failed || s == wire::JOB_FAILED || s == wire::JOB_STATE_UNSPECIFIED;
    all_done = all_done && s == wire::JOB_DONE;
  }
  if (active) return running || done ? wire::JOB_RUNNING : wire::JOB_QUEUED;
  if (all_done) return wire::JOB_DONE;
  return failed ? wire::JOB_FAILED : wire::JOB_CANCELLED;
}

wire::JobStatus JobManager::sequence_status(const std::string& id, const Sequence& q,
                                            uint32_t workers_total, bool with_frames) const {
  const std::vector<std::string>& frames = q.frames;
  wire::JobStatus out;
  out.set_job_id(id);
  out.set_state(sequence_state(q));
  out.set_frames_total(static_cast<uint32_t>(frames.size()));
  out.set_workers_total(workers_total);
  uint32_t done = 0;
  bool first = true, all_paused = true, any_active = false;
  double spp_mean = 0.0, samples = 0.0;
  uint32_t spp_min = 0;
  int64_t started = 0, finished = 0;  // its first frame's start, its last frame's end
  bool all_ended = true;
  for (const std::string& f : frames) {
    auto it = jobs_.find(f);
    if (it == jobs_.end()) continue;
    const Job& job = it->second;
    const wire::JobStatus st = make_status(job, workers_total);
    if (first) {
      out.set_name(sequence_name(job.record.spec));
      out.set_owner(st.owner());
      out.set_width(st.width());
      out.set_height(st.height());
      *out.mutable_settings() = st.settings();
      out.set_tile_size(st.tile_size());
      out.set_pass_spp(st.pass_spp());
      out.set_passes_total(st.passes_total());
      out.set_priority(st.priority());
      out.set_passes_done(st.passes_done());
      out.set_submitted_unix_ms(st.submitted_unix_ms());
      spp_min = st.spp_done();
      first = false;
    }
    if (st.started_unix_ms() > 0 && (started == 0 || st.started_unix_ms() < started)) {
      started = st.started_unix_ms();
    }
    finished = std::max(finished, st.finished_unix_ms());
    all_ended = all_ended && st.finished_unix_ms() > 0;
    if (st.state() == wire::JOB_DONE) ++done;
    if (!out.has_frame() && st.state() != wire::JOB_DONE && st.has_frame()) {
      out.set_frame(st.frame());  // the first frame not done
    }
    if (is_active_state(st.state())) {
      if (!any_active) out.set_priority(st.priority());
      any_active = true;
      all_paused = all_paused && st.paused();
    }
    if (out.error().empty() && !st.error().empty() && st.state() != wire::JOB_CANCELLED) {
      out.set_error(fmt::format("frame {}: {}", st.frame(), st.error()));
    }
    if (out.storage_error().empty() && !st.storage_error().empty()) {
      out.set_storage_error(fmt::format("frame {}: {}", st.frame(), st.storage_error()));
    }
    out.set_units_total(out.units_total() + st.units_total());
    out.set_units_done(out.units_done() + st.units_done());
    out.set_units_leased(out.units_leased() + st.units_leased());
    out.set_tiles_total(out.tiles_total() + st.tiles_total());
    out.set_tiles_converged(out.tiles_converged() + st.tiles_converged());
    out.set_workers_busy(out.workers_busy() + st.workers_busy());
    samples += st.spp_mean() * double(st.width()) * double(st.height());
    spp_min = std::min(spp_min, st.spp_done());
    out.set_passes_done(std::min(out.passes_done(), st.passes_done()));  // over every frame
    spp_mean += st.spp_mean();
    if (with_frames) {
      wire::SequenceFrame* sf = out.add_frames();
      sf->set_frame(st.frame());
      sf->set_job_id(f);
      sf->set_state(st.state());
      sf->set_paused(st.paused());
      sf->set_percent(st.units_total() ? 100.0 * double(st.units_done()) / double(st.units_total())
                                       : 0.0);
    }
  }
  out.set_frames_done(done);
  out.set_started_unix_ms(started);
  out.set_finished_unix_ms(all_ended && !is_active_state(out.state()) ? finished : 0);
  out.set_previews(previews_note(id, q));
  out.set_paused(is_active_state(out.state()) && (q.paused || (any_active && all_paused)));
  out.set_priority(q.priority);
  out.set_spp_done(spp_min);
  out.set_spp_mean(frames.empty() ? 0.0 : spp_mean / double(frames.size()));
  // The sequence's own clock: wall time since its first unit went out, pauses left out. Its
  // frames overlap (several render at once on a large farm), so the sum of their times, or of
  // their rates, says nothing of the sequence's: the rate is every sample merged over that
  // wall time.
  const double elapsed = q.elapsed(Clock::now());
  out.set_elapsed_seconds(elapsed);
  if (elapsed > 0) out.set_samples_per_second(samples / elapsed);
  out.set_est_rel_mse(-1.0);
  out.set_ref_rel_mse(-1.0);
  // The time so far over the units done so far, times the units left; none while paused.
  if (out.state() == wire::JOB_DONE) {
    out.set_eta_seconds(0.0);
  } else if (out.units_done() > 0 && elapsed > 0 && is_active_state(out.state()) &&
             !out.paused()) {
    out.set_eta_seconds(elapsed * double(out.units_total() - out.units_done()) /
                        double(out.units_done()));
  } else {
    out.set_eta_seconds(-1.0);
  }
  return out;
}

void JobManager::update_previews(const std::string& id, bool missing_only) {
  auto it = sequences_.find(id);
  if (it == sequences_.end()) return;
  SequencePreviews::Request request;
  request.sequence = id;
  request.dir = store_.job_dir(id);
  bool any_done = false, all_done = true;
  for (const std::string& f : it->second.frames) {
    auto job = jobs_.find(f);
    if (job == jobs_.end()) continue;
    const bool done = job->second.record.state == wire::JOB_DONE;
    request.frames.push_back(
        {job->second.record.spec.frame.value_or(0), store_.image_path(f), done});
    any_done = any_done || done;
    all_done = all_done && done;
  }
  if (!any_done) return;
  std::error_code ec;
  request.sheet = !missing_only;
  if (missing_only) {
    // Left by a stop while a movie was being made: its temporary file and log.
    for (const auto& entry : fs::directory_iterator(request.dir, ec)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind(std::string(SequencePreviews::kMovieName) + ".", 0) == 0) {
        fs::remove(entry.path(), ec);
      }
    }
    // A sheet older than a finished frame misses it (a stop before it was rewritten).
    const auto sheet_time = fs::last_write_time(request.dir / SequencePreviews::kSheetName, ec);
    request.sheet = ec.operator bool();
    for (const SequencePreviews::Frame& f : request.frames) {
      if (request.sheet) break;
      if (f.done) request.sheet = fs::last_write_time(f.exr, ec) > sheet_time || ec;
    }
  }
  request.movie = all_done && previews_.makes_movies() &&
                  (!missing_only || !fs::exists(request.dir / SequencePreviews::kMovieName, ec));
  if (!request.sheet && !request.movie) return;
  request.fps = store_.sequence_fps(id);
  previews_.submit(std::move(request));
}

std::string JobManager::previews_note(const std::string& id, const Sequence& q) const {
  const fs::path dir = store_.job_dir(id);
  std::error_code ec;
  std::string note = fs::exists(dir / SequencePreviews::kSheetName, ec)
                         ? "contact sheet"
                         : "contact sheet when a frame is done";
  const std::string failure = previews_.movie_failure(id);
  if (fs::exists(dir / SequencePreviews::kMovieName, ec)) {
    note += "; movie";
  } else if (!failure.empty()) {
    note += "; no movie: " + failure;
  } else if (!previews_.makes_movies()) {
    note += "; no movie (turned off)";
  } else if (sequence_state(q) == wire::JOB_DONE) {
    note += "; movie being made";
  } else if (!is_active_state(sequence_state(q))) {
    note += "; no movie: not every frame is done";
  } else {
    note += "; movie when every frame is done";
  }
  return note;
}

}  // namespace rayfarm::master
