// Sequences: a sequence's frames are jobs of their own ("j0007.0012", each with its record,
// checkpoints, image and error record), and the sequence ("j0007") is what its client submitted
// and acts on. These fan a request for a sequence out to its frames, and sum their status.
// docs/farm.md, "Frame sequences".
#include <algorithm>

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

const std::vector<std::string>* JobManager::sequence_frames(const std::string& id) const {
  auto it = sequences_.find(id);
  if (it == sequences_.end()) return nullptr;
  // A sequence none of whose frames is left (a removal cut short) is unknown, as it would be
  // after a restart.
  for (const std::string& f : it->second) {
    if (jobs_.count(f)) return &it->second;
  }
  return nullptr;
}

wire::JobState JobManager::cancel_sequence(const std::vector<std::string>& frames) {
  for (const std::string& f : frames) {
    auto it = jobs_.find(f);
    if (it != jobs_.end() && it->second.active) {
      finish(it->second, wire::JOB_CANCELLED, "cancelled by a client");
    }
  }
  return sequence_state(frames);
}

const JobRecord* JobManager::change_sequence(const std::string& id,
                                             const std::vector<std::string>& frames,
                                             std::optional<int32_t> priority,
                                             std::optional<bool> paused) {
  const JobRecord* first = nullptr;
  for (const std::string& f : frames) {
    auto it = jobs_.find(f);
    if (it == jobs_.end() || !it->second.active || it->second.active->finishing) continue;
    const JobRecord* r = change_one(f, priority, paused);
    if (first == nullptr) first = r;
  }
  if (first == nullptr) {
    throw JobRejected(fmt::format(
        "sequence {} is {}: only a queued or running sequence can be paused, resumed or given a "
        "priority",
        id, protocol::job_state_name(sequence_state(frames))));
  }
  return first;
}

void JobManager::remove_sequence(const std::string& id) {
  const std::vector<std::string> frames = sequences_.at(id);
  for (const std::string& f : frames) {
    auto it = jobs_.find(f);
    if (it != jobs_.end() && it->second.active) {
      throw JobRejected(
          fmt::format("sequence {} has frames queued or running (frame {}): cancel "
                      "it first",
                      id, it->second.record.spec.frame.value_or(0)));
    }
  }
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

wire::JobState JobManager::retry_sequence(const std::string& id,
                                          const std::vector<std::string>& frames) {
  size_t retried = 0;
  for (const std::string& f : frames) {
    auto it = jobs_.find(f);
    if (it == jobs_.end() || it->second.record.unreadable) continue;
    const wire::JobState s = it->second.record.state;
    if (s == wire::JOB_FAILED || s == wire::JOB_CANCELLED) {
      retry(f);
      ++retried;
    }
  }
  if (retried == 0) {
    throw JobRejected(fmt::format("sequence {} has no failed or cancelled frame to retry", id));
  }
  return sequence_state(frames);
}

wire::JobState JobManager::sequence_state(const std::vector<std::string>& frames) const {
  bool active = false, running = false, done = false, failed = false, all_done = true;
  for (const std::string& f : frames) {
    auto it = jobs_.find(f);
    const wire::JobState s = it == jobs_.end() ? wire::JOB_FAILED : it->second.record.state;
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

wire::JobStatus JobManager::sequence_status(const std::string& id,
                                            const std::vector<std::string>& frames,
                                            uint32_t workers_total, bool with_frames) const {
  wire::JobStatus out;
  out.set_job_id(id);
  out.set_state(sequence_state(frames));
  out.set_frames_total(static_cast<uint32_t>(frames.size()));
  out.set_workers_total(workers_total);
  uint32_t done = 0;
  bool first = true, all_paused = true, any_active = false;
  double elapsed = 0.0, spp_mean = 0.0;
  uint32_t spp_min = 0;
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
      spp_min = st.spp_done();
      first = false;
    }
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
    out.set_samples_per_second(out.samples_per_second() + st.samples_per_second());
    spp_min = std::min(spp_min, st.spp_done());
    out.set_passes_done(std::min(out.passes_done(), st.passes_done()));  // over every frame
    spp_mean += st.spp_mean();
    elapsed += st.elapsed_seconds();
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
  out.set_previews(previews_note(id, frames));
  out.set_paused(any_active && all_paused);
  out.set_spp_done(spp_min);
  out.set_spp_mean(frames.empty() ? 0.0 : spp_mean / double(frames.size()));
  out.set_elapsed_seconds(elapsed);
  out.set_est_rel_mse(-1.0);
  out.set_ref_rel_mse(-1.0);
  // The frames mostly render one after another: the time so far over the units done so far.
  if (out.state() == wire::JOB_DONE) {
    out.set_eta_seconds(0.0);
  } else if (out.units_done() > 0 && elapsed > 0 && is_active_state(out.state())) {
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
  for (const std::string& f : it->second) {
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

std::string JobManager::previews_note(const std::string& id,
                                      const std::vector<std::string>& frames) const {
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
  } else if (sequence_state(frames) == wire::JOB_DONE) {
    note += "; movie being made";
  } else if (!is_active_state(sequence_state(frames))) {
    note += "; no movie: not every frame is done";
  } else {
    note += "; movie when every frame is done";
  }
  return note;
}

}  // namespace rayfarm::master
