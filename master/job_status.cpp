// Status: what `status`, `list` and `image` report of a job, queued, running or finished.
#include <set>

#include "common/protocol/convert.h"
#include "master/eta.h"
#include "master/job_manager.h"
#include "master/job_text.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;
using namespace detail;

namespace {

/// A worker that returned a result this recently counts as active on the job.
constexpr std::chrono::seconds kActiveWindow{10};

}  // namespace

double JobManager::elapsed(const Job& job) {
  return job.active ? job.active->elapsed() : job.record.elapsed_seconds;
}

uint32_t JobManager::workers_active(const ActiveJob& job) {
  const auto now = Clock::now();
  std::set<WorkerId> active;
  for (const auto& [worker, when] : job.contributors) {
    if (now - when <= kActiveWindow) active.insert(worker);
  }
  return static_cast<uint32_t>(active.size());
}

wire::JobStatus JobManager::make_status(const Job& job, uint32_t workers_total) const {
  const JobSpec& s = job.record.spec;
  wire::JobStatus st;
  st.set_job_id(s.id);
  st.set_name(s.name);
  st.set_owner(s.owner);
  if (s.frame) st.set_frame(*s.frame);
  st.set_sequence(s.sequence);
  st.set_state(job.record.state);
  if (job.record.unreadable) {  // only its id and what is wrong are known
    st.set_error(job.record.error);
    st.set_est_rel_mse(-1.0);
    st.set_ref_rel_mse(-1.0);
    st.set_eta_seconds(-1.0);
    st.set_workers_total(workers_total);
    return st;
  }
  st.set_width(s.film.width);
  st.set_height(s.film.height);
  *st.mutable_settings() = protocol::settings_to_wire(s.settings);
  st.set_tile_size(s.tile_size);
  st.set_pass_spp(s.pass_spp);
  st.set_target_error(s.stop.target_error);
  st.set_submitted_unix_ms(s.submitted_unix_ms);
  st.set_started_unix_ms(job.record.started_unix_ms);
  st.set_finished_unix_ms(job.active ? 0 : job.record.finished_unix_ms);
  const UnitGrid grid(s.film, s.tile_size, s.settings.spp, s.pass_spp);
  st.set_passes_total(grid.pass_count());
  st.set_units_total(grid.size());
  st.set_elapsed_seconds(elapsed(job));
  st.set_workers_total(workers_total);
  st.set_error(job.record.error);
  st.set_eta_seconds(-1.0);
  st.set_stop_reason(job.record.stop_reason);
  st.set_tiles_total(grid.tile_count());
  st.set_est_rel_mse(job.record.est_rel_mse);
  st.set_ref_rel_mse(job.record.ref_rel_mse);
  st.set_spp_mean(job.record.spp_mean);
  st.set_tiles_converged(job.record.tiles_converged);
  st.set_storage_error(for_clients(job.storage_error));
  st.set_error(for_clients(job.record.error));
  // A frame's priority is its sequence's, and a paused sequence holds every frame.
  const Sequence* q = sequence_of(s);
  st.set_priority(q ? q->priority : job.record.priority);
  st.set_paused(job.record.paused || (q && q->paused && job.active));
  if (job.active) {
    const ActiveJob& a = *job.active;
    const Merger& m = a.merger;
    const auto counts = scheduler_.counts(s.id);
    st.set_passes_done(grid.passes_within(m.min_spp()));
    st.set_tiles_converged(a.planner.tiles_converged());
    st.set_spp_mean(static_cast<double>(m.samples_merged()) /
                    (double(s.film.width) * s.film.height));
    if (!a.rows.empty()) {
      const ErrorRow& row = a.rows.back();
      st.set_est_rel_mse(row.est_rel_mse);
      if (row.ref_rel_mse) st.set_ref_rel_mse(*row.ref_rel_mse);
    }
    st.set_units_done(m.merged_count());
    st.set_units_leased(counts.leased);
    st.set_spp_done(m.min_spp());
    st.set_workers_busy(counts.workers);
    const double seconds = elapsed(job);
    if (seconds > 0 && m.samples_merged() > 0) {
      const double rate = static_cast<double>(m.samples_merged()) / seconds;
      st.set_samples_per_second(rate);
      // A paused job's end is the user's to say: no estimate.
      if (!st.paused())
        st.set_eta_seconds(
            estimate_eta(s.stop, static_cast<double>(grid.samples_total() - m.samples_merged()),
                         rate, seconds, a.rows));
    }
  } else {
    st.set_units_done(job.record.units_done);
    st.set_spp_done(job.record.spp_min);
    // Records from before passes_done was kept: every pass when the job ran to its spp.
    const bool all_passes = job.record.state == wire::JOB_DONE &&
                            (job.record.stop_reason.empty() || job.record.stop_reason == "spp");
    st.set_passes_done(job.record.passes_done > 0 ? job.record.passes_done
                       : all_passes               ? grid.pass_count()
                                                  : 0);
    if (job.record.state == wire::JOB_DONE) st.set_eta_seconds(0.0);
    if (job.record.elapsed_seconds > 0) {
      st.set_samples_per_second(job.record.spp_mean * s.film.width * s.film.height /
                                job.record.elapsed_seconds);
    }
  }
  return st;
}

std::optional<wire::JobStatus> JobManager::status(const std::string& id,
                                                  uint32_t workers_total) const {
  if (sequence_frames(id)) {
    return sequence_status(id, sequences_.at(id), workers_total, /*with_frames=*/true);
  }
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return std::nullopt;
  return make_status(it->second, workers_total);
}

std::vector<wire::JobStatus> JobManager::list(uint32_t workers_total) const {
  // A sequence is one line, where its first frame would be.
  std::vector<wire::JobStatus> out;
  std::set<std::string> listed;  // sequences
  for (const auto& [id, job] : jobs_) {
    const std::string& sequence = job.record.spec.sequence;
    const auto* frames = sequence.empty() ? nullptr : sequence_frames(sequence);
    if (frames == nullptr) {
      out.push_back(make_status(job, workers_total));
    } else if (listed.insert(sequence).second) {
      out.push_back(
          sequence_status(sequence, sequences_.at(sequence), workers_total, /*with_frames=*/false));
    }
  }
  return out;
}

wire::ImageData JobManager::image(const std::string& id, bool movie, bool sheet) const {
  if (const auto* frames = sequence_frames(id)) {
    if (!movie && !sheet) {
      throw JobRejected(
          fmt::format("{} is a sequence of {} frames: fetch one frame (--frame N), all of them "
                      "(--all), its contact sheet (-o NAME.png) or its movie (-o NAME.mp4)",
                      id, frames->size()));
    }
    // A sequence's images are its frames'; of its own it has its previews.
    wire::ImageData out;
    out.set_job_id(id);
    const Sequence& q = sequences_.at(id);
    out.set_state(sequence_state(q));
    const auto read = [&](const char* name) { return store_.read_file(id, name); };
    if (movie) {
      auto mp4 = read(SequencePreviews::kMovieName);
      if (!mp4) {
        throw JobRejected(
            fmt::format("sequence {} has no movie ({})", id, previews_note(id, q)));
      }
      out.set_mp4(std::move(*mp4));
      return out;
    }
    auto png = read(SequencePreviews::kSheetName);
    if (!png) {
      throw JobRejected(
          fmt::format("sequence {} has no contact sheet yet (no frame is done); its frames: "
                      "--frame N or --all",
                      id));
    }
    out.set_png(std::move(*png));
    return out;
  }
  auto it = jobs_.find(id);
  if (it != jobs_.end() && movie) {
    throw JobRejected("job " + id + " is not a sequence: it has no movie");
  }
  if (it == jobs_.end()) throw JobRejected("unknown job '" + id + "'");
  auto exr = store_.read_file(id, "image.exr");
  if (!exr) throw JobRejected("job " + id + " has no image yet (no unit has been merged)");
  wire::ImageData out;
  out.set_job_id(id);
  out.set_exr(std::move(*exr));
  if (auto png = store_.read_file(id, "image.png")) out.set_png(std::move(*png));
  if (auto csv = store_.read_file(id, "error.csv")) out.set_error_csv(std::move(*csv));
  if (auto plot = store_.read_file(id, "error.png")) out.set_error_png(std::move(*plot));
  const Job& job = it->second;
  out.set_spp_done(job.active ? job.active->merger.min_spp() : job.record.spp_min);
  out.set_state(job.record.state);
  return out;
}

std::optional<wire::Bundle> JobManager::bundle(const std::string& hash) const {
  auto it = bundle_owner_.find(hash);
  if (it == bundle_owner_.end()) return std::nullopt;
  return store_.load_bundle(it->second);
}

void JobManager::rebind_bundle(const std::string& hash, const std::string& gone) {
  // Bundles are served from a folder that has them: another job's with the same scene, if any.
  auto owner = bundle_owner_.find(hash);
  if (owner == bundle_owner_.end() || owner->second != gone) return;
  bundle_owner_.erase(owner);
  for (const auto& [other, j] : jobs_) {
    if (!j.record.unreadable && j.record.spec.bundle_hash == hash &&
        JobStore::bundle_holder(j.record.spec) != gone) {
      bundle_owner_.emplace(hash, JobStore::bundle_holder(j.record.spec));
      break;
    }
  }
}

std::vector<std::string> JobManager::units_of(const WorkerId& worker) const {
  std::vector<std::string> out;
  for (const UnitRef& u : scheduler_.leased_units(worker))
    out.push_back(fmt::format("{}/{}", u.job, u.unit));
  return out;
}

std::string JobManager::for_clients(const std::string& text) const {
  std::string out = text;
  std::error_code ec;
  const fs::path absolute = fs::absolute(store_.root(), ec);
  if (!ec && !absolute.empty()) out = replace_all(out, absolute.string(), "<data dir>");
  return replace_all(out, store_.root().string(), "<data dir>");
}

}  // namespace rayfarm::master
