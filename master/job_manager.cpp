#include "master/job_manager.h"

#include "master/eta.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <set>
#include <system_error>

#include "common/bundle/bundle.h"
#include "common/image/film_output.h"
#include "common/net/frames.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/parser.h"
#include "common/util/atomic_file.h"
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

std::string describe_stop(const StopRules& stop, uint32_t spp) {
  std::string out = fmt::format("{} spp", spp);
  if (stop.target_error > 0) {
    out += fmt::format(", target relMSE {:g} ({})", stop.target_error,
                       stop.adaptive ? "per tile" : "whole passes");
  }
  if (stop.time_limit_s > 0) out += fmt::format(", time limit {:g} s", stop.time_limit_s);
  return out;
}

/// What a client is told when the master cannot store its job (the cause, without the master's
/// paths); the master's log has the whole message.
std::string storage_refusal(const std::exception& e, const fs::path& root) {
  log_jobs()->error("cannot store a submitted job in {}: {}", root.string(), e.what());
  const int code = storage_error_code(e);
  std::string cause = code ? std::generic_category().message(code) : "an I/O error";
  cause[0] = static_cast<char>(std::tolower(static_cast<unsigned char>(cause[0])));
  return "the master cannot store the job: " + cause + " (the master's data dir)";
}

}  // namespace

Image JobManager::check_reference_bytes(const std::string& exr, FilmSize film) const {
  fs::path scratch;
  try {
    scratch = store_.make_scratch_dir();
    write_file_atomically(scratch / "reference.exr", exr);
  } catch (const std::exception& e) {
    std::error_code ec;
    if (!scratch.empty()) fs::remove_all(scratch, ec);
    throw JobRejected(storage_refusal(e, store_.root()));
  }
  std::error_code ec;
  Image reference;
  try {
    // The header's size is checked against the film before any pixel is allocated, so a
    // reference costs at most the film's size, whatever its header claims.
    reference = read_exr(scratch / "reference.exr", ExrExpect{film.width, film.height, true});
    check_reference(reference, film, "reference image");
  } catch (const std::exception& e) {
    fs::remove_all(scratch, ec);
    throw JobRejected(replace_all(e.what(), (scratch / "reference.exr").string(),
                                  "reference image"));
  }
  fs::remove_all(scratch, ec);
  return reference;
}

JobManager::JobManager(JobStore& store, JobManagerOptions options)
    : store_(store), options_(std::move(options)) {}

std::string JobManager::name_of(const WorkerId& worker) const {
  return options_.worker_name ? options_.worker_name(worker) : net::peer_label(worker);
}

void JobManager::activate(Job& job, std::optional<Image> preloaded) {
  const JobSpec& s = job.record.spec;
  job.merger = std::make_unique<Merger>(UnitGrid(s.film, s.tile_size, s.settings.spp, s.pass_spp));
  job.planner = std::make_unique<PassPlanner>(job.merger->grid(), s.stop);
  scheduler_.add_job(s.id, job.merger->grid().size(), job.planner->gated());
  if (job.planner->gated()) scheduler_.release(s.id, job.planner->take_released());
  std::optional<Image> reference = std::move(preloaded);
  if (s.has_reference && !reference) {
    try {
      reference = load_reference(store_.reference_path(s.id), s.film);
    } catch (const std::exception& e) {
      log_jobs()->error("job {}: its reference image cannot be read ({}); the error is only "
                        "estimated",
                        s.id, e.what());
    }
  }
  job.tracker = std::make_unique<ErrorTracker>(job.merger->grid().tiles(), std::move(reference));
  job.rows.clear();
  job.unit_failures.clear();
  job.worker_failures.clear();
  job.lease_history.clear();
  job.all_blocked_since.reset();
  job.checkpoint_due = false;
  job.last_checkpoint = Clock::now();
  job.rounds_recorded = 0;
  job.samples_recorded = 0;
  job.record.state = wire::JOB_QUEUED;
  job.started = false;
  job.dirty = false;
}

size_t JobManager::recover() {
  size_t restarted = 0;
  for (JobRecord& record : store_.load_records()) {
    const std::string id = record.spec.id;
    Job job;
    job.record = std::move(record);
    if (job.record.unreadable) {  // listed as it is, with its cause; never saved over
      jobs_.emplace(id, std::move(job));
      continue;
    }
    bundle_owner_.emplace(job.record.spec.bundle_hash, id);
    if (is_active_state(job.record.state)) {
      if (!store_.load_bundle(id)) {
        job.record.state = wire::JOB_FAILED;
        job.record.error = "the job's bundle is missing from the data dir";
        log_jobs()->error("job {}: {}; marked failed", id, job.record.error);
        save(job);
      } else {
        const bool was_running = job.record.state == wire::JOB_RUNNING;
        activate(job);
        ++restarted;
        bool resumed = false;
        try {
          resumed = resume(job);
        } catch (const std::exception& e) {  // e.g. out of memory: start over rather than stop
          log_jobs()->error("job {}: its checkpoint cannot be loaded ({}); starting over", id,
                            e.what());
          scheduler_.remove_job(id);
          activate(job);
        }
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
    if (inserted && it->second.planner && it->second.planner->finished()) {
      finish(it->second, wire::JOB_DONE, "", it->second.planner->reason());
    }
  }
  return restarted;
}

bool JobManager::resume(Job& job) {
  const JobSpec& s = job.record.spec;
  const UnitGrid grid(s.film, s.tile_size, s.settings.spp, s.pass_spp);
  // Builds the merged state a checkpoint describes, checking it against the job's settings.
  auto rebuild = [&](const Checkpoint& c, Merger& merger, PassPlanner& planner) {
    if (c.job_id != s.id || c.width != s.film.width || c.height != s.film.height ||
        c.tile_size != s.tile_size || c.spp != s.settings.spp || c.pass_spp != s.pass_spp) {
      throw CheckpointError(fmt::format(
          "it is of job '{}' {}x{}, tile {}, {} spp in passes of {}, not of this job's settings",
          c.job_id, c.width, c.height, c.tile_size, c.spp, c.pass_spp));
    }
    try {
      merger.restore(c.merged, c.sum, c.sum_sq, c.pixel_spp, c.nonfinite, c.rays);
      planner.import_state(c.planner);
    } catch (const std::invalid_argument& e) {
      throw CheckpointError(std::string("inconsistent: ") + e.what());
    }
    for (uint32_t t = 0; t < grid.tile_count(); ++t) {
      uint32_t merged = 0;
      for (uint32_t p = 0; p < grid.pass_count(); ++p) {
        const uint64_t unit = grid.id(p, t);
        if (!c.merged[unit]) continue;
        ++merged;
        if (!planner.is_released(unit)) {
          throw CheckpointError(fmt::format("inconsistent: unit {} is merged but not released",
                                            unit));
        }
      }
      if (merged != c.planner.tiles[t].merged) {
        throw CheckpointError(fmt::format(
            "inconsistent: tile {} has {} merged units, the planner counts {}", t, merged,
            c.planner.tiles[t].merged));
      }
    }
    if (!(c.elapsed_seconds >= 0) || c.rows.size() > grid.size() + 1) {
      throw CheckpointError("inconsistent: bad elapsed time or error rows");
    }
  };
  auto fresh_planner = [&] { return std::make_unique<PassPlanner>(grid, s.stop); };
  std::vector<std::string> problems;
  auto loaded = load_newest_checkpoint(store_.job_dir(s.id), problems, [&](const Checkpoint& c) {
    Merger merger(grid);
    rebuild(c, merger, *fresh_planner());
  });
  for (const std::string& problem : problems) {
    log_jobs()->error("job {}: cannot use checkpoint {}{}", s.id, problem,
                      loaded ? fmt::format("; falling back to {}", loaded->file.string())
                             : std::string("; no other checkpoint to fall back to"));
  }
  if (!loaded) return false;
  const Checkpoint& c = loaded->checkpoint;
  auto merger = std::make_unique<Merger>(grid);
  auto planner = fresh_planner();
  rebuild(c, *merger, *planner);
  // The scheduler: merged units are done, released ones pending.
  std::vector<uint64_t> released;
  for (uint64_t unit = 0; unit < grid.size(); ++unit) {
    if (c.merged[unit]) scheduler_.complete(UnitRef{s.id, unit});
    if (planner->is_released(unit)) released.push_back(unit);
  }
  if (planner->gated()) scheduler_.release(s.id, released);
  planner->take_released();
  job.merger = std::move(merger);
  job.planner = std::move(planner);
  job.tracker->estimate_all(job.merger->film());
  job.rows = c.rows;
  job.rounds_recorded = c.rounds_recorded;
  job.samples_recorded = c.samples_recorded;
  job.checkpoint_sequence = c.sequence;
  checkpoints_.set_newest_slot(s.id, loaded->slot);
  if (c.elapsed_seconds > 0 || job.merger->merged_count() > 0) {
    job.started = true;
    job.start_time = Clock::now() - std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(c.elapsed_seconds));
    job.record.state = wire::JOB_RUNNING;
  }
  log_jobs()->info(
      "job {} resumed from checkpoint at {}/{} units, pass {} ({:.1f} s rendered; {}, checkpoint "
      "{})",
      s.id, job.merger->merged_count(), grid.size(), job.planner->rounds_complete(),
      c.elapsed_seconds, loaded->file.string(), c.sequence);
  if (job.merger->merged_count() > 0) write_image(job);
  return true;
}

void JobManager::checkpoint(Job& job) {
  const JobSpec& s = job.record.spec;
  const Merger& m = *job.merger;
  Checkpoint c;
  c.sequence = ++job.checkpoint_sequence;
  c.job_id = s.id;
  c.width = s.film.width;
  c.height = s.film.height;
  c.tile_size = s.tile_size;
  c.spp = s.settings.spp;
  c.pass_spp = s.pass_spp;
  c.elapsed_seconds = elapsed(job);
  c.merged = m.merged_map();
  c.sum = m.film().sum();
  c.sum_sq = m.film().sum_sq();
  c.pixel_spp = m.film().spp();
  c.nonfinite = m.film().nonfinite();
  c.rays = m.film().rays();
  c.planner = job.planner->export_state();
  c.rows = job.rows;
  c.rounds_recorded = job.rounds_recorded;
  c.samples_recorded = job.samples_recorded;
  checkpoints_.submit(store_.job_dir(s.id), std::move(c));
  job.checkpoint_due = false;
  job.last_checkpoint = Clock::now();
}

size_t JobManager::shutdown() {
  size_t count = 0;
  for (auto& [id, job] : jobs_) {
    if (!job.merger || !job.started) continue;  // finished, or nothing to keep yet
    if (job.dirty) write_image(job);
    checkpoint(job);
    ++count;
  }
  checkpoints_.flush();
  writer_.flush();
  if (count) {
    log_jobs()->info("{} running job{} checkpointed; they resume there when the master starts again",
                     count, count == 1 ? "" : "s");
  }
  return count;
}

void JobManager::record_row(Job& job) {
  // Every merge updated its tile's estimate (on_result): the image's estimate is a sum over
  // tiles here (the row still counts samples, and compares with the reference when there is one).
  job.rows.push_back(job.tracker->record(job.merger->film(), elapsed(job), /*tiles_current=*/true));
  job.samples_recorded = job.merger->samples_merged();
}

const std::string* JobManager::owner_of(const std::string& id) const {
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : &it->second.record.spec.owner;
}

std::string JobManager::submit(const wire::SubmitJob& request, const std::string& owner) {
  return admit(prepare(request, owner));
}

JobManager::PreparedJob JobManager::prepare(const wire::SubmitJob& request,
                                            const std::string& owner) const {
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
  fs::path scratch;
  try {
    scratch = store_.make_scratch_dir();
  } catch (const std::exception& e) {
    throw JobRejected(storage_refusal(e, store_.root()));
  }
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
    if (is_storage_error(e)) throw JobRejected(storage_refusal(e, store_.root()));
    throw JobRejected(std::string("bad bundle: ") + e.what());
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove_all(scratch, ec);
    if (is_storage_error(e)) throw JobRejected(storage_refusal(e, store_.root()));
    throw;
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
  if (!(o.clamp() >= 0.f) || !std::isfinite(o.clamp())) {
    throw JobRejected(fmt::format("clamp must be 0 (off) or positive, got {}", o.clamp()));
  }
  spec.settings.clamp = o.clamp();
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
  if (o.width() != 0 || o.height() != 0) {
    if (o.width() == 0 || o.height() == 0) {
      throw JobRejected(fmt::format("the film override needs a width and a height, got {}x{}",
                                    o.width(), o.height()));
    }
    spec.film = {o.width(), o.height()};
  }
  if (spec.film.width == 0 || spec.film.height == 0) throw JobRejected("the scene's film is empty");
  spec.stop.target_error = o.target_error();
  spec.stop.time_limit_s = o.time_limit_s();
  spec.stop.adaptive = !o.no_adaptive();
  spec.stop.min_passes = o.min_passes();
  try {
    check_stop_rules(spec.stop);
  } catch (const std::invalid_argument& e) {
    throw JobRejected(e.what());
  }
  spec.has_reference = !request.reference_exr().empty();
  PreparedJob prepared;
  if (spec.has_reference)
    prepared.reference = check_reference_bytes(request.reference_exr(), spec.film);
  const UnitGrid grid(spec.film, spec.tile_size, spec.settings.spp, spec.pass_spp);
  if (grid.size() > kMaxUnits) {
    throw JobRejected(
        fmt::format("{} units of work is too many (limit {}); use larger tiles or passes",
                    grid.size(), kMaxUnits));
  }
  spec.submitted_unix_ms = unix_ms_now();
  spec.owner = owner;

  // Store it; admit() schedules it.
  try {
    spec.id = store_.allocate_id();
  } catch (const std::exception& e) {
    throw JobRejected(storage_refusal(e, store_.root()));
  }
  JobRecord record;
  record.spec = spec;
  try {
    wire::Bundle canonical;
    protocol::bundle_to_wire(bundle, &canonical);
    store_.save_bundle(spec.id, canonical);
    if (spec.has_reference) store_.save_reference(spec.id, request.reference_exr());
    store_.save_record(record);  // throws: a job is accepted only once it is on disk
    store_.sync_job_dir(spec.id);
  } catch (const std::exception& e) {
    fs::remove_all(store_.job_dir(spec.id), ec);
    throw JobRejected(storage_refusal(e, store_.root()));
  }
  prepared.spec = std::move(spec);
  prepared.warnings = scene.warnings;
  prepared.bundle_files = bundle.files.size();
  prepared.bundle_bytes = bundle.data_bytes();
  return prepared;
}

std::string JobManager::admit(PreparedJob prepared) {
  const JobSpec& spec = prepared.spec;
  const UnitGrid grid(spec.film, spec.tile_size, spec.settings.spp, spec.pass_spp);
  const std::string& hash = spec.bundle_hash;
  Job job;
  job.record.spec = spec;
  bundle_owner_.emplace(hash, spec.id);
  try {
    activate(job, std::move(prepared.reference));
  } catch (const std::exception& e) {
    // E.g. no memory for the job's film: it is on disk, so it is recorded as failed (and listed)
    // rather than tried again at every start.
    scheduler_.remove_job(spec.id);
    job.merger.reset();
    job.planner.reset();
    job.tracker.reset();
    job.record.state = wire::JOB_FAILED;
    job.record.error = std::string("the master cannot hold the job: ") + e.what();
    job.record.stop_reason = stop_reason_name(StopReason::kFailed);
    log_jobs()->error("job {}: {}", spec.id, job.record.error);
    const std::string error = job.record.error;
    auto [it, inserted] = jobs_.emplace(spec.id, std::move(job));
    save(it->second);
    throw JobRejected(error);
  }
  log_jobs()->info(
      "job {} accepted: '{}', scene {} {}x{}, {}, {}, max depth {}, seed {}; {} tiles of {} x "
      "{} passes of {} spp = {} units; bundle of {} files, {} ({}){}",
      spec.id, spec.name, spec.scene_path, spec.film.width, spec.film.height,
      describe_stop(spec.stop, spec.settings.spp), integrator_name(spec.settings.integrator),
      spec.settings.max_depth, spec.settings.seed, grid.tile_count(), spec.tile_size,
      grid.pass_count(), spec.pass_spp, grid.size(), prepared.bundle_files,
      human_bytes(prepared.bundle_bytes), hash.substr(0, 12),
      spec.has_reference ? "; error measured against its reference image" : "");
  for (const auto& w : prepared.warnings) log_jobs()->warn("job {}: {}", spec.id, w);
  const std::string id = spec.id;
  jobs_.emplace(id, std::move(job));
  return id;
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
  const JobSpec& s = job.record.spec;
  {
    // The unit's past holders: kept until it merges, the latest few (a unit handed out again and
    // again to reconnecting workers must not grow without bound).
    constexpr size_t kHoldersKept = 8;
    auto& holders = job.lease_history[ref->unit];
    const std::pair<WorkerId, std::string> holder{worker, key};
    if (std::find(holders.begin(), holders.end(), holder) == holders.end()) {
      if (holders.size() >= kHoldersKept) holders.erase(holders.begin());
      holders.push_back(holder);
    }
  }
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
  out.set_film_width(s.film.width);  // the job's film, which may override the scene's
  out.set_film_height(s.film.height);
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
  if (!job.merger) {
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
  if (job.finishing) {
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
  if (job.merger->merged(result.unit_id())) {
    log_merger()->log(level(), "job {} unit {}: duplicate result from {} dropped (merged before)", id,
                      result.unit_id(), name_of(worker));
    return MergeOutcome::kDuplicate;
  }
  // Only the connection that was leased the unit may return it: another peer's result, even with
  // a valid worker key, is dropped and counts against nobody (it cannot fail the job either).
  const auto history = job.lease_history.find(result.unit_id());
  if (history == job.lease_history.end() ||
      std::find(history->second.begin(), history->second.end(), std::pair{worker, key}) ==
          history->second.end()) {
    log_merger()->debug("job {} unit {}: result from {} dropped: the unit was never leased to it",
                        id, result.unit_id(), name_of(worker));
    return MergeOutcome::kUnleased;
  }
  if (!job.planner->is_released(result.unit_id())) {
    return reject("the unit was never handed out (the job's stopping rules have not released it)");
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

  scheduler_.complete(ref, worker);
  job.lease_history.erase(result.unit_id());
  job.dirty = true;
  job.checkpoint_due = true;
  job.contributors[worker] = Clock::now();
  log_merger()->debug("job {} unit {} merged from {} ({:.3f} s render)", id, result.unit_id(),
                      name_of(worker), result.render_seconds());
  job.tracker->update_tile(job.merger->film(), job.merger->grid().tile_of(result.unit_id()));
  PassPlanner& planner = *job.planner;
  planner.on_merged(result.unit_id(), job.merger->film());
  if (planner.gated()) scheduler_.release(id, planner.take_released());
  if (planner.rounds_complete() > job.rounds_recorded) on_round_done(job);
  if (planner.finished()) finish(job, wire::JOB_DONE, "", planner.reason());
  return outcome;
}

void JobManager::on_round_done(Job& job) {
  const Merger& m = *job.merger;
  const PassPlanner& planner = *job.planner;
  const JobSpec& s = job.record.spec;
  job.rounds_recorded = planner.rounds_complete();
  const double seconds = elapsed(job);
  record_row(job);
  const ErrorRow& row = job.rows.back();
  const double eta =
      estimate_eta(s.stop, static_cast<double>(m.grid().samples_total() - m.samples_merged()),
                   row.samples_per_s, seconds, job.rows);
  // The per-tile figure: the tile with the largest estimated error, and where it is.
  const TiledErrorEstimate& tiles = job.tracker->estimate();
  const int worst_tile = tiles.worst_tile();
  const double worst = worst_tile >= 0 ? tiles.tile(worst_tile).rel_mse : -1.0;
  const TileRect worst_rect = worst_tile >= 0 ? tiles.tiles()[worst_tile] : TileRect{};
  log_jobs()->info(
      "job {} pass {}/{} done: {:.1f} spp, estimated relMSE {:.3g} (RMSE {:.3g}){}{}{}, {}, ETA "
      "{:.1f} s, {} workers active",
      s.id, job.rounds_recorded, m.grid().pass_count(), row.spp, row.est_rel_mse, row.est_rmse,
      worst >= 0 ? fmt::format(", worst tile at ({}, {}) {:.3g}", worst_rect.x0, worst_rect.y0, worst)
                 : "",
      planner.gated() ? fmt::format(", {}/{} tiles converged", planner.tiles_converged(),
                                    planner.tile_count())
                      : "",
      row.ref_rel_mse ? fmt::format(", measured relMSE {:.3g}", *row.ref_rel_mse) : "",
      human_rate(row.samples_per_s), eta, workers_active(job));
  write_image(job);
  checkpoint(job);
}

bool JobManager::on_unit_failed(const WorkerId& worker, const wire::UnitFailed& failed,
                                const std::string& key) {
  auto it = jobs_.find(failed.job_id());
  if (it == jobs_.end() || !it->second.merger) return false;
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
  if (!job.merger) return;
  // Failures count per key: every connection made with one key is one worker here, so that one
  // key can block only itself and never fail a job alone.
  const std::string& who = key.empty() ? worker : key;
  const std::string label =
      key.empty() ? name_of(worker)
                  : fmt::format("key '{}' ({})", protocol::printable(key), name_of(worker));
  const int worker_count = ++job.worker_failures[who];
  auto& on_unit = job.unit_failures[unit];
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
  if (!job.merger || job.finishing || job.worker_failures.empty() || !options_.connected_workers) {
    return false;
  }
  const std::vector<std::string> connected = options_.connected_workers();
  const bool all_blocked = !connected.empty() &&
                           std::all_of(connected.begin(), connected.end(),
                                       [&](const auto& w) { return scheduler_.is_blocked(id, w); });
  if (!all_blocked) {
    job.all_blocked_since.reset();
    return false;
  }
  if (!job.all_blocked_since) job.all_blocked_since = now;
  if (now - *job.all_blocked_since < options_.blocked_grace) return false;
  std::string last;
  for (const auto& [unit, on_unit] : job.unit_failures) {
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

void JobManager::remove(const std::string& id) {
  auto it = jobs_.find(id);
  if (it == jobs_.end()) throw JobRejected("unknown job '" + id + "'");
  Job& job = it->second;
  if (job.merger) {
    throw JobRejected(fmt::format("job {} is {}: cancel it first", id,
                                  protocol::job_state_name(job.record.state)));
  }
  writer_.flush();  // no image of it is still on its way to the folder
  std::error_code ec;
  fs::remove_all(store_.job_dir(id), ec);
  if (ec) {
    throw JobRejected(
        fmt::format("cannot remove {}: {}", store_.job_dir(id).string(), ec.message()));
  }
  const std::string hash = job.record.spec.bundle_hash;
  jobs_.erase(it);
  // Bundles are served by a job that has them: another one with the same scene, if any.
  auto owner = bundle_owner_.find(hash);
  if (owner != bundle_owner_.end() && owner->second == id) {
    bundle_owner_.erase(owner);
    for (const auto& [other, j] : jobs_) {
      if (!j.record.unreadable && j.record.spec.bundle_hash == hash) {
        bundle_owner_.emplace(hash, other);
        break;
      }
    }
  }
  log_jobs()->info("job {} removed with its files", id);
}

wire::JobState JobManager::retry(const std::string& id) {
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
  if (!store_.load_bundle(id)) {
    throw JobRejected("job " + id + " cannot be retried: its bundle is missing from the data dir");
  }
  writer_.flush();
  for (const char* name : {"image.exr", "image.png", "error.csv", "error.png"}) {
    std::error_code ec;
    fs::remove(store_.job_dir(id) / name, ec);
  }
  JobRecord& r = job.record;
  const JobSpec spec = r.spec;
  r = JobRecord{};
  r.spec = spec;
  job.contributors.clear();
  job.storage_error.clear();
  job.record_unsaved = false;
  activate(job);
  save(job);
  log_jobs()->info("job {} queued again ('{}'): retried after it {}", id, spec.name,
                   state == wire::JOB_FAILED ? "failed" : "was cancelled");
  return job.record.state;
}

std::vector<std::string> JobManager::units_of(const WorkerId& worker) const {
  std::vector<std::string> out;
  for (const UnitRef& u : scheduler_.leased_units(worker))
    out.push_back(fmt::format("{}/{}", u.job, u.unit));
  return out;
}

void JobManager::finish(Job& job, wire::JobState state, const std::string& error,
                        StopReason reason) {
  JobSpec& s = job.record.spec;
  if (reason == StopReason::kRunning) {
    reason = state == wire::JOB_CANCELLED ? StopReason::kCancelled
             : state == wire::JOB_FAILED  ? StopReason::kFailed
                                          : StopReason::kSpp;
  }
  // The record as it will be once the job has ended.
  JobRecord final_record = job.record;
  final_record.stop_reason = stop_reason_name(reason);
  final_record.elapsed_seconds = job.finishing ? job.finishing->elapsed : elapsed(job);
  final_record.state = state;
  final_record.error = error;
  bool write_final_image = false;
  if (job.merger) {
    // The last row of the error record describes the final image.
    if (job.merger->samples_merged() > job.samples_recorded) {
      record_row(job);
      job.dirty = true;
    }
    write_final_image = state == wire::JOB_DONE || job.dirty || job.finishing.has_value();
    JobRecord& r = final_record;
    r.units_done = job.merger->merged_count();
    r.spp_min = job.merger->min_spp();
    // Leading passes every pixel has (a converged tile skips the later ones).
    r.passes_done = r.spp_min >= s.settings.spp ? job.merger->grid().pass_count()
                                                : r.spp_min / std::max<uint32_t>(1, s.pass_spp);
    r.spp_mean = static_cast<double>(job.merger->samples_merged()) /
                 (double(s.film.width) * s.film.height);
    r.tiles_converged = job.planner->tiles_converged();
    if (!job.rows.empty()) {
      r.est_rel_mse = job.rows.back().est_rel_mse;
      if (job.rows.back().ref_rel_mse) r.ref_rel_mse = *job.rows.back().ref_rel_mse;
    }
  }
  scheduler_.remove_job(s.id);  // no more units either way
  if (job.merger && state == wire::JOB_DONE) {
    // Done means on disk: the final image and the record. Until both are, the job stays running
    // with its checkpoints, and tick() tries again.
    const std::string problem = store_final(job, final_record, write_final_image);
    if (!problem.empty()) {
      if (!job.finishing) {
        job.finishing = Job::Finishing{state, error, reason, final_record.elapsed_seconds};
        checkpoint(job);  // the merged state, in case the master stops before the disk recovers
      }
      storage_failed(job, problem);
      return;
    }
  } else if (job.merger && write_final_image) {
    write_image(job, /*wait=*/true);  // a cancelled or failed job keeps what it rendered
  }
  const uint64_t samples = job.merger ? job.merger->samples_merged() : 0;
  const std::string error_summary =
      job.merger && !job.rows.empty()
          ? fmt::format(", estimated relMSE {:.3g}{}", job.rows.back().est_rel_mse,
                        job.rows.back().ref_rel_mse
                            ? fmt::format(", measured {:.3g}", *job.rows.back().ref_rel_mse)
                            : "")
          : "";
  const bool record_saved = state == wire::JOB_DONE && job.merger != nullptr;
  job.record = std::move(final_record);
  job.merger.reset();
  job.planner.reset();
  job.tracker.reset();
  job.rows.clear();
  job.lease_history.clear();
  job.unit_failures.clear();
  job.finishing.reset();
  // The record says how the job ended; its checkpoints are of no use any more once it is on
  // disk (until then they are what a restarted master resumes from).
  if (record_saved || save(job)) {
    job.storage_error.clear();
    checkpoints_.forget(s.id, store_.job_dir(s.id));
  }
  const double seconds = job.record.elapsed_seconds;
  if (state == wire::JOB_DONE) {
    log_jobs()->info("job {} done ({}): '{}' {}x{}, {:.1f} spp mean in {:.2f} s ({}){}; image {}",
                     s.id, job.record.stop_reason, s.name, s.film.width, s.film.height,
                     static_cast<double>(samples) / (double(s.film.width) * s.film.height),
                     seconds, human_rate(seconds > 0 ? samples / seconds : 0.0), error_summary,
                     (store_.job_dir(s.id) / "image.exr").string());
  } else if (state == wire::JOB_CANCELLED) {
    log_jobs()->info("job {} cancelled after {:.2f} s at {} spp", s.id, seconds, job.record.spp_min);
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
  log_jobs()->error("job {}: {}{}; trying again in {:.0f} s", job.record.spec.id, what,
                    job.finishing ? " (its work is done: it stays running, with its checkpoints, "
                                    "until its final image and record are on disk)"
                                  : "",
                    job.storage_backoff.count() / 1000.0);
}

void JobManager::write_image(Job& job, bool wait) {
  const JobSpec& s = job.record.spec;
  // The same attributes as `rayfarm render`, plus the job's own.
  std::map<std::string, std::string> attributes{
      {"rayfarm:integrator", integrator_name(s.settings.integrator)},
      {"rayfarm:seed", std::to_string(s.settings.seed)},
      {"rayfarm:max_depth", std::to_string(s.settings.max_depth)},
      {"rayfarm:scene", fs::path(s.scene_path).filename().string()},
      {"rayfarm:job", s.id},
      {"rayfarm:spp_target", std::to_string(s.settings.spp)}};
  if (s.settings.clamp > 0) attributes["rayfarm:clamp"] = fmt::format("{:g}", s.settings.clamp);
  // The same pixels as `rayfarm render` (film_to_image), written on the writer's thread.
  ImageWriter::ErrorRecord record;
  record.rows = job.rows;
  record.title = fmt::format("job {} '{}' ({})", s.id, s.name, integrator_name(s.settings.integrator));
  writer_.submit(store_.image_path(s.id), film_to_image(job.merger->film(), attributes),
                 std::move(record));
  if (wait) writer_.flush();
  job.dirty = false;
  job.last_write = Clock::now();
}

void JobManager::tick() {
  const auto now = Clock::now();
  for (auto& [id, job] : jobs_) {
    if (!job.storage_error.empty() && now >= job.storage_retry) {
      if (job.finishing) {
        const Job::Finishing f = *job.finishing;
        finish(job, f.state, f.error, f.reason);
      } else if (job.record_unsaved) {
        if (save(job)) {
          job.storage_error.clear();
          if (!job.merger) checkpoints_.forget(id, store_.job_dir(id));
          log_jobs()->info("job {}: its record is on disk again", id);
        }
      } else {
        // An image or checkpoint failure: cleared once a later write succeeds.
        std::string failure = writer_.failure(store_.image_path(id));
        if (failure.empty()) failure = checkpoints_.failure(id);
        if (failure.empty() || !job.merger) {
          job.storage_error.clear();
        } else {
          storage_failed(job, failure);
        }
      }
      if (job.storage_error.empty()) job.storage_backoff = std::chrono::milliseconds{0};
      continue;
    }
    if (job.finishing) continue;
    if (fail_if_nobody_can_render(job, now)) continue;
    if (job.merger) {
      // Failures of the writer threads show in the job's status until a later write succeeds.
      std::string failure = writer_.failure(store_.image_path(id));
      if (failure.empty()) failure = checkpoints_.failure(id);
      if (!failure.empty() && job.storage_error.empty()) storage_failed(job, failure);
    }
    const double limit = job.record.spec.stop.time_limit_s;
    if (job.merger && job.started && limit > 0 && elapsed(job) >= limit) {
      log_jobs()->info("job {}: time limit of {:g} s reached", id, limit);
      finish(job, wire::JOB_DONE, "", StopReason::kTimeLimit);
      continue;
    }
    if (job.merger && job.dirty && now - job.last_write >= options_.image_interval)
      write_image(job);
    if (job.merger && job.checkpoint_due && options_.checkpoint_interval.count() > 0 &&
        now - job.last_checkpoint >= options_.checkpoint_interval) {
      checkpoint(job);
    }
  }
}

size_t JobManager::active_jobs() const {
  return static_cast<size_t>(std::count_if(
      jobs_.begin(), jobs_.end(), [](const auto& kv) { return kv.second.merger != nullptr; }));
}

bool JobManager::save(Job& job) {
  if (job.record.unreadable) return true;  // its job.json stays as it is, for a look
  try {
    store_.save_record(job.record);
  } catch (const std::exception& e) {
    job.record_unsaved = true;
    storage_failed(job, std::string("cannot save the job's record: ") + e.what());
    return false;
  }
  job.record_unsaved = false;
  return true;
}

std::string JobManager::for_clients(const std::string& text) const {
  std::string out = text;
  std::error_code ec;
  const fs::path absolute = fs::absolute(store_.root(), ec);
  if (!ec && !absolute.empty()) out = replace_all(out, absolute.string(), "<data dir>");
  return replace_all(out, store_.root().string(), "<data dir>");
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
  st.set_owner(s.owner);
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
  if (job.merger) {
    const Merger& m = *job.merger;
    const auto counts = scheduler_.counts(s.id);
    st.set_passes_done(job.planner->rounds_complete());
    st.set_tiles_converged(job.planner->tiles_converged());
    st.set_spp_mean(static_cast<double>(m.samples_merged()) /
                    (double(s.film.width) * s.film.height));
    if (!job.rows.empty()) {
      const ErrorRow& row = job.rows.back();
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
      st.set_eta_seconds(
          estimate_eta(s.stop, static_cast<double>(grid.samples_total() - m.samples_merged()), rate,
                       seconds, job.rows));
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
  if (auto csv = store_.read_file(id, "error.csv")) out.set_error_csv(std::move(*csv));
  if (auto plot = store_.read_file(id, "error.png")) out.set_error_png(std::move(*plot));
  const Job& job = it->second;
  out.set_spp_done(job.merger ? job.merger->min_spp() : job.record.spp_min);
  out.set_state(job.record.state);
  return out;
}

std::optional<wire::Bundle> JobManager::bundle(const std::string& hash) const {
  auto it = bundle_owner_.find(hash);
  if (it == bundle_owner_.end()) return std::nullopt;
  return store_.load_bundle(it->second);
}

}  // namespace rayfarm::master
