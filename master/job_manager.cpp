#include "master/job_manager.h"

#include <algorithm>
#include <set>
#include <system_error>

#include "common/bundle/bundle.h"
#include "common/image/film_output.h"
#include "common/net/frames.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/parser.h"
#include "common/util/log.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;

namespace {

constexpr uint32_t kDefaultTileSize = 64;
constexpr uint32_t kMaxTileSize = 4096;
constexpr uint32_t kMaxSpp = uint32_t{1} << 24;
constexpr uint32_t kMaxDepth = 1024;
constexpr uint64_t kMaxUnits = uint64_t{1} << 26;
/// A worker that returned a result this recently counts as active on the job.
constexpr std::chrono::seconds kActiveWindow{10};

std::shared_ptr<spdlog::logger> log_jobs() { return get_logger("jobs"); }
std::shared_ptr<spdlog::logger> log_merger() { return get_logger("merger"); }
std::shared_ptr<spdlog::logger> log_scheduler() { return get_logger("scheduler"); }

std::string replace_all(std::string text, const std::string& from, const std::string& to) {
  if (from.empty()) return text;
  for (size_t pos = text.find(from); pos != std::string::npos;
       pos = text.find(from, pos + to.size())) {
    text.replace(pos, from.size(), to);
  }
  return text;
}

std::string human_bytes(uint64_t bytes) {
  if (bytes >= (uint64_t{1} << 20)) return fmt::format("{:.1f} MiB", bytes / 1048576.0);
  if (bytes >= 1024) return fmt::format("{:.1f} KiB", bytes / 1024.0);
  return fmt::format("{} B", bytes);
}

std::string human_rate(double samples_per_second) {
  if (samples_per_second >= 1e6) return fmt::format("{:.2f} Msamples/s", samples_per_second / 1e6);
  if (samples_per_second >= 1e3) return fmt::format("{:.1f} ksamples/s", samples_per_second / 1e3);
  return fmt::format("{:.0f} samples/s", samples_per_second);
}

bool is_active_state(wire::JobState s) { return s == wire::JOB_QUEUED || s == wire::JOB_RUNNING; }

int64_t unix_ms_now() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

JobManager::JobManager(JobStore& store, JobManagerOptions options)
    : store_(store), options_(std::move(options)) {}

std::string JobManager::name_of(const WorkerId& worker) const {
  return options_.worker_name ? options_.worker_name(worker) : net::peer_label(worker);
}

void JobManager::activate(Job& job) {
  const JobSpec& s = job.record.spec;
  job.merger = std::make_unique<Merger>(UnitGrid(s.film, s.tile_size, s.settings.spp, s.pass_spp));
  scheduler_.add_job(s.id, job.merger->grid().size());
  job.record.state = wire::JOB_QUEUED;
  job.started = false;
  job.passes_logged = 0;
  job.dirty = false;
}

size_t JobManager::recover() {
  size_t restarted = 0;
  for (JobRecord& record : store_.load_records()) {
    const std::string id = record.spec.id;
    bundle_owner_.emplace(record.spec.bundle_hash, id);
    Job job;
    job.record = std::move(record);
    if (is_active_state(job.record.state)) {
      if (!store_.load_bundle(id)) {
        job.record.state = wire::JOB_FAILED;
        job.record.error = "the job's bundle is missing from the data dir";
        log_jobs()->error("job {}: {}; marked failed", id, job.record.error);
        save(job);
      } else {
        activate(job);
        save(job);
        ++restarted;
        log_jobs()->info(
            "job {} restarted from the beginning ('{}', {}x{}, {} spp): partial sums "
            "are not kept across master restarts",
            id, job.record.spec.name, job.record.spec.film.width, job.record.spec.film.height,
            job.record.spec.settings.spp);
      }
    } else if (job.record.state == wire::JOB_DONE) {
      const JobSpec& s = job.record.spec;
      job.units_done = UnitGrid(s.film, s.tile_size, s.settings.spp, s.pass_spp).size();
      job.spp_done = s.settings.spp;
    }
    jobs_.emplace(id, std::move(job));
  }
  return restarted;
}

std::string JobManager::submit(const wire::SubmitJob& request) {
  // The bundle and the scene path.
  Bundle bundle;
  try {
    bundle = protocol::bundle_from_wire(request.bundle());
    check_bundle_path(request.scene_path());
  } catch (const BundleError& e) {
    throw JobRejected(std::string("bad bundle: ") + e.what());
  }
  if (std::none_of(bundle.files.begin(), bundle.files.end(),
                   [&](const BundleFile& f) { return f.path == request.scene_path(); })) {
    throw JobRejected("the scene file '" + request.scene_path() + "' is not in the bundle");
  }
  const std::string hash = bundle_hash(bundle);

  // The scene must load here before the job is accepted.
  Scene scene;
  const fs::path scratch = store_.make_scratch_dir();
  try {
    const fs::path dir = unpack_bundle(bundle, scratch, hash);
    try {
      scene = load_scene(dir / request.scene_path());
    } catch (const std::exception& e) {
      throw JobRejected(replace_all(e.what(), dir.string() + "/", ""));
    }
  } catch (const BundleError& e) {
    std::error_code ec;
    fs::remove_all(scratch, ec);
    throw JobRejected(std::string("bad bundle: ") + e.what());
  } catch (...) {
    std::error_code ec;
    fs::remove_all(scratch, ec);
    throw;
  }
  std::error_code ec;
  fs::remove_all(scratch, ec);

  // Settings: the scene's, with the job's overrides.
  JobSpec spec;
  spec.name =
      protocol::printable(request.name().empty() ? request.scene_path() : request.name(), 128);
  spec.bundle_hash = hash;
  spec.scene_path = request.scene_path();
  spec.film = scene.film;
  spec.settings = scene.render;
  const wire::JobOverrides& o = request.overrides();
  if (o.has_spp()) spec.settings.spp = o.spp();
  if (o.has_max_depth()) spec.settings.max_depth = o.max_depth();
  if (o.has_seed()) spec.settings.seed = o.seed();
  if (o.integrator() != wire::INTEGRATOR_UNSPECIFIED) {
    try {
      spec.settings.integrator = protocol::integrator_from_wire(o.integrator());
    } catch (const protocol::ProtocolError& e) {
      throw JobRejected(e.what());
    }
  }
  if (spec.settings.spp == 0 || spec.settings.spp > kMaxSpp) {
    throw JobRejected(fmt::format("spp must be in [1, {}], got {}", kMaxSpp, spec.settings.spp));
  }
  if (spec.settings.max_depth > kMaxDepth) {
    throw JobRejected(
        fmt::format("max depth must be at most {}, got {}", kMaxDepth, spec.settings.max_depth));
  }
  spec.tile_size = o.tile_size() == 0 ? kDefaultTileSize : o.tile_size();
  if (spec.tile_size > kMaxTileSize) {
    throw JobRejected(
        fmt::format("tile size must be in [1, {}], got {}", kMaxTileSize, spec.tile_size));
  }
  spec.pass_spp = o.pass_spp() == 0 ? default_pass_spp(spec.tile_size, spec.settings.spp)
                                    : std::min(o.pass_spp(), spec.settings.spp);
  if (spec.film.width == 0 || spec.film.height == 0) throw JobRejected("the scene's film is empty");
  const UnitGrid grid(spec.film, spec.tile_size, spec.settings.spp, spec.pass_spp);
  if (grid.size() > kMaxUnits) {
    throw JobRejected(
        fmt::format("{} units of work is too many (limit {}); use larger tiles or passes",
                    grid.size(), kMaxUnits));
  }
  spec.submitted_unix_ms = unix_ms_now();

  // Store it, then schedule it.
  spec.id = store_.allocate_id();
  Job job;
  job.record.spec = spec;
  try {
    wire::Bundle canonical;
    protocol::bundle_to_wire(bundle, &canonical);
    store_.save_bundle(spec.id, canonical);
    save(job);
  } catch (const std::exception& e) {
    fs::remove_all(store_.job_dir(spec.id), ec);
    throw JobRejected(std::string("the master cannot store the job: ") + e.what());
  }
  bundle_owner_.emplace(hash, spec.id);
  activate(job);
  log_jobs()->info(
      "job {} accepted: '{}', scene {} {}x{}, {} spp, {}, max depth {}, seed {}; {} tiles of {} x "
      "{} passes of {} spp = {} units; bundle of {} files, {} ({})",
      spec.id, spec.name, spec.scene_path, spec.film.width, spec.film.height, spec.settings.spp,
      integrator_name(spec.settings.integrator), spec.settings.max_depth, spec.settings.seed,
      grid.tile_count(), spec.tile_size, grid.pass_count(), spec.pass_spp, grid.size(),
      bundle.files.size(), human_bytes(bundle.data_bytes()), hash.substr(0, 12));
  for (const auto& w : scene.warnings) log_jobs()->warn("job {}: {}", spec.id, w);
  jobs_.emplace(spec.id, std::move(job));
  return spec.id;
}

std::optional<wire::WorkUnit> JobManager::next_unit(const WorkerId& worker) {
  const auto ref = scheduler_.lease(worker);
  if (!ref) return std::nullopt;
  Job& job = jobs_.at(ref->job);
  const JobSpec& s = job.record.spec;
  if (!job.started) {
    job.started = true;
    job.start_time = Clock::now();
    job.last_write = job.start_time;
    job.record.state = wire::JOB_RUNNING;
    save(job);
    log_jobs()->info("job {} started", s.id);
  }
  const UnitGrid::Unit u = job.merger->grid().unit(ref->unit);
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
  log_scheduler()->debug("job {} unit {} (pass {}) leased to {}", s.id, u.id, u.pass,
                         name_of(worker));
  return out;
}

MergeOutcome JobManager::on_result(const WorkerId& worker, const wire::UnitResult& result) {
  const std::string& id = result.job_id();
  auto it = jobs_.find(id);
  if (it == jobs_.end()) {
    log_merger()->warn("result for unknown job '{}' from {} dropped", id, name_of(worker));
    return MergeOutcome::kRejected;
  }
  Job& job = it->second;
  const UnitRef ref{id, result.unit_id()};
  if (!job.merger) {
    if (job.record.state == wire::JOB_DONE) {
      log_merger()->info("job {} unit {}: duplicate result from {} dropped (the job is done)", id,
                         result.unit_id(), name_of(worker));
      return MergeOutcome::kDuplicate;
    }
    log_merger()->info("job {} unit {}: result from {} dropped (the job is {})", id,
                       result.unit_id(), name_of(worker),
                       protocol::job_state_name(job.record.state));
    return MergeOutcome::kRejected;
  }
  auto reject = [&](const std::string& why) {
    log_merger()->warn("job {} unit {}: result from {} rejected: {}", id, result.unit_id(),
                       name_of(worker), why);
    if (scheduler_.holder(ref) == worker) scheduler_.requeue(ref);
    return MergeOutcome::kRejected;
  };
  if (job.merger->merged(result.unit_id())) {
    log_merger()->info("job {} unit {}: duplicate result from {} dropped (merged before)", id,
                       result.unit_id(), name_of(worker));
    return MergeOutcome::kDuplicate;
  }
  TileResult tile;
  try {
    tile = protocol::result_from_wire(result);
  } catch (const protocol::ProtocolError& e) {
    return reject(e.what());
  }
  std::string why;
  const MergeOutcome outcome = job.merger->add(result.unit_id(), tile, &why);
  if (outcome == MergeOutcome::kRejected) return reject(why);
  if (outcome == MergeOutcome::kDuplicate) return outcome;  // checked above; kept for clarity

  scheduler_.complete(ref);
  job.dirty = true;
  job.contributors[worker] = Clock::now();
  log_merger()->debug("job {} unit {} merged from {} ({:.3f} s render)", id, result.unit_id(),
                      name_of(worker), result.render_seconds());
  if (job.merger->passes_complete() > job.passes_logged) on_pass_done(job);
  if (job.merger->complete()) finish(job, wire::JOB_DONE, "");
  return outcome;
}

void JobManager::on_pass_done(Job& job) {
  const Merger& m = *job.merger;
  const JobSpec& s = job.record.spec;
  job.passes_logged = m.passes_complete();
  const uint32_t spp_done =
      m.grid().unit(uint64_t{job.passes_logged} * m.grid().tile_count() - 1).samples.end;
  const double seconds = elapsed(job);
  const double rate = seconds > 0 ? static_cast<double>(m.samples_merged()) / seconds : 0.0;
  const double remaining = static_cast<double>(m.grid().samples_total() - m.samples_merged());
  log_jobs()->info(
      "job {} pass {}/{} done: {}/{} spp ({:.0f}%), {}, ETA {:.1f} s, {} workers active", s.id,
      job.passes_logged, m.grid().pass_count(), spp_done, s.settings.spp,
      100.0 * spp_done / s.settings.spp, human_rate(rate), rate > 0 ? remaining / rate : 0.0,
      workers_active(job));
  write_image(job);
}

void JobManager::on_unit_failed(const WorkerId& worker, const wire::UnitFailed& failed) {
  auto it = jobs_.find(failed.job_id());
  if (it == jobs_.end() || !it->second.merger) return;
  Job& job = it->second;
  const UnitRef ref{failed.job_id(), failed.unit_id()};
  const int count = ++job.failures[failed.unit_id()];
  log_jobs()->warn("job {} unit {} failed on {} (attempt {} of {}): {}", ref.job, ref.unit,
                   name_of(worker), count, options_.max_unit_failures, failed.reason());
  if (scheduler_.holder(ref) == worker) scheduler_.requeue(ref);
  if (count >= options_.max_unit_failures) {
    finish(job, wire::JOB_FAILED,
           fmt::format("unit {} failed {} times; last on {}: {}", ref.unit, count, name_of(worker),
                       failed.reason()));
  }
}

size_t JobManager::release_worker(const WorkerId& worker) {
  for (auto& [id, job] : jobs_) job.contributors.erase(worker);
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
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return std::nullopt;
  if (it->second.merger) finish(it->second, wire::JOB_CANCELLED, "cancelled by a client");
  return it->second.record.state;
}

void JobManager::finish(Job& job, wire::JobState state, const std::string& error) {
  JobSpec& s = job.record.spec;
  if (job.merger) {
    // The final image is on disk before the job is reported finished.
    if (state == wire::JOB_DONE || job.dirty) write_image(job, /*wait=*/true);
    job.units_done = job.merger->merged_count();
    job.spp_done = job.merger->film().min_spp();
  }
  job.record.elapsed_seconds = elapsed(job);
  job.record.state = state;
  job.record.error = error;
  scheduler_.remove_job(s.id);
  const uint64_t samples = job.merger ? job.merger->samples_merged() : 0;
  job.merger.reset();
  save(job);
  const double seconds = job.record.elapsed_seconds;
  if (state == wire::JOB_DONE) {
    log_jobs()->info("job {} done: '{}' {}x{}, {} spp in {:.2f} s ({}); image {}", s.id, s.name,
                     s.film.width, s.film.height, s.settings.spp, seconds,
                     human_rate(seconds > 0 ? samples / seconds : 0.0),
                     (store_.job_dir(s.id) / "image.exr").string());
  } else if (state == wire::JOB_CANCELLED) {
    log_jobs()->info("job {} cancelled after {:.2f} s at {} spp", s.id, seconds, job.spp_done);
  } else {
    log_jobs()->error("job {} failed after {:.2f} s: {}", s.id, seconds, error);
  }
}

void JobManager::write_image(Job& job, bool wait) {
  const JobSpec& s = job.record.spec;
  // The same attributes as `rayfarm render`, plus the job's own.
  const std::map<std::string, std::string> attributes{
      {"rayfarm:integrator", integrator_name(s.settings.integrator)},
      {"rayfarm:seed", std::to_string(s.settings.seed)},
      {"rayfarm:max_depth", std::to_string(s.settings.max_depth)},
      {"rayfarm:scene", fs::path(s.scene_path).filename().string()},
      {"rayfarm:job", s.id},
      {"rayfarm:spp_target", std::to_string(s.settings.spp)}};
  // The same pixels as `rayfarm render` (film_to_image), written on the writer's thread.
  writer_.submit(store_.image_path(s.id), film_to_image(job.merger->film(), attributes));
  if (wait) writer_.flush();
  job.dirty = false;
  job.last_write = Clock::now();
}

void JobManager::tick() {
  const auto now = Clock::now();
  for (auto& [id, job] : jobs_) {
    if (job.merger && job.dirty && now - job.last_write >= options_.image_interval)
      write_image(job);
  }
}

size_t JobManager::active_jobs() const {
  return static_cast<size_t>(std::count_if(
      jobs_.begin(), jobs_.end(), [](const auto& kv) { return kv.second.merger != nullptr; }));
}

void JobManager::save(const Job& job) {
  try {
    store_.save_record(job.record);
  } catch (const std::exception& e) {
    log_jobs()->error("job {}: cannot save its record: {}", job.record.spec.id, e.what());
  }
}

double JobManager::elapsed(const Job& job) const {
  if (!job.merger) return job.record.elapsed_seconds;
  if (!job.started) return 0.0;
  return std::chrono::duration<double>(Clock::now() - job.start_time).count();
}

uint32_t JobManager::workers_active(const Job& job) const {
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
  st.set_state(job.record.state);
  st.set_width(s.film.width);
  st.set_height(s.film.height);
  *st.mutable_settings() = protocol::settings_to_wire(s.settings);
  st.set_tile_size(s.tile_size);
  st.set_pass_spp(s.pass_spp);
  const UnitGrid grid(s.film, s.tile_size, s.settings.spp, s.pass_spp);
  st.set_passes_total(grid.pass_count());
  st.set_units_total(grid.size());
  st.set_elapsed_seconds(elapsed(job));
  st.set_workers_total(workers_total);
  st.set_error(job.record.error);
  st.set_eta_seconds(-1.0);
  if (job.merger) {
    const Merger& m = *job.merger;
    const auto counts = scheduler_.counts(s.id);
    st.set_passes_done(m.passes_complete());
    st.set_units_done(m.merged_count());
    st.set_units_leased(counts.leased);
    st.set_spp_done(m.film().min_spp());
    st.set_workers_busy(counts.workers);
    const double seconds = elapsed(job);
    if (seconds > 0 && m.samples_merged() > 0) {
      const double rate = static_cast<double>(m.samples_merged()) / seconds;
      st.set_samples_per_second(rate);
      st.set_eta_seconds(static_cast<double>(grid.samples_total() - m.samples_merged()) / rate);
    }
  } else {
    st.set_units_done(job.units_done);
    st.set_spp_done(job.spp_done);
    st.set_passes_done(job.record.state == wire::JOB_DONE ? grid.pass_count() : 0);
    if (job.record.state == wire::JOB_DONE) st.set_eta_seconds(0.0);
    if (job.record.elapsed_seconds > 0) {
      st.set_samples_per_second(static_cast<double>(grid.samples_total()) *
                                (job.record.state == wire::JOB_DONE ? 1.0 : 0.0) /
                                job.record.elapsed_seconds);
    }
  }
  return st;
}

std::optional<wire::JobStatus> JobManager::status(const std::string& id,
                                                  uint32_t workers_total) const {
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return std::nullopt;
  return make_status(it->second, workers_total);
}

std::vector<wire::JobStatus> JobManager::list(uint32_t workers_total) const {
  std::vector<wire::JobStatus> out;
  for (const auto& [id, job] : jobs_) out.push_back(make_status(job, workers_total));
  return out;
}

wire::ImageData JobManager::image(const std::string& id) const {
  auto it = jobs_.find(id);
  if (it == jobs_.end()) throw JobRejected("unknown job '" + id + "'");
  auto exr = store_.read_file(id, "image.exr");
  if (!exr) throw JobRejected("job " + id + " has no image yet (no unit has been merged)");
  wire::ImageData out;
  out.set_job_id(id);
  out.set_exr(std::move(*exr));
  if (auto png = store_.read_file(id, "image.png")) out.set_png(std::move(*png));
  const Job& job = it->second;
  out.set_spp_done(job.merger ? job.merger->film().min_spp() : job.spp_done);
  out.set_state(job.record.state);
  return out;
}

std::optional<wire::Bundle> JobManager::bundle(const std::string& hash) const {
  auto it = bundle_owner_.find(hash);
  if (it == bundle_owner_.end()) return std::nullopt;
  return store_.load_bundle(it->second);
}

}  // namespace rayfarm::master
