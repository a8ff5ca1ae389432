// Admission: what `submit` checks before a job is accepted (the bundle, the scene, the settings
// and their limits, the reference image), storing the job, and scheduling it.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <set>
#include <string_view>
#include <system_error>

#include "common/bundle/bundle.h"
#include "common/limits.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/frame_files.h"
#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "common/util/atomic_file.h"
#include "master/job_manager.h"
#include "master/job_text.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;
using namespace detail;

namespace {

/// The job's shutter overrides applied to `s`; false when only one end is given.
bool apply_shutter_overrides(const wire::JobOverrides& o, RenderSettings& s) {
  if (o.has_shutter_open() != o.has_shutter_close()) return false;
  if (o.has_shutter_open()) {
    s.shutter_open = o.shutter_open();
    s.shutter_close = o.shutter_close();
  }
  if (o.has_motion_steps()) s.motion_steps = o.motion_steps();
  return true;
}

constexpr uint64_t kMaxUnits = uint64_t{1} << 26;

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
    throw JobRejected(
        replace_all(e.what(), (scratch / "reference.exr").string(), "reference image"));
  }
  fs::remove_all(scratch, ec);
  return reference;
}

const std::string* JobManager::owner_of(const std::string& id) const {
  if (const auto* frames = sequence_frames(id)) {
    for (const std::string& f : *frames) {
      if (auto it = jobs_.find(f); it != jobs_.end()) return &it->second.record.spec.owner;
    }
    return nullptr;
  }
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : &it->second.record.spec.owner;
}

std::string JobManager::submit(const wire::SubmitJob& request, const std::string& owner) {
  return admit(prepare(request, owner));
}

JobManager::PreparedJob JobManager::prepare(const wire::SubmitJob& request,
                                            const std::string& owner,
                                            const SceneCheck& check) const {
  if (request.priority() < kMinPriority || request.priority() > kMaxPriority) {
    throw JobRejected(fmt::format("priority {} is out of range ({} to {})", request.priority(),
                                  kMinPriority, kMaxPriority));
  }
  // A sequence's frames.
  std::optional<FrameList> frames;
  try {
    frames = protocol::frames_from_wire(request.frames());
  } catch (const protocol::ProtocolError& e) {
    throw JobRejected(e.what());
  }
  if (request.has_frame() &&
      (request.frame() < -kMaxFrameNumber || request.frame() > kMaxFrameNumber)) {
    throw JobRejected(fmt::format("frame {} is out of range (frame numbers are within +-{})",
                                  request.frame(), kMaxFrameNumber));
  }
  if (frames && request.has_frame()) {
    throw JobRejected("a job is one frame or a sequence of frames, not both");
  }
  if (frames && !request.reference_exr().empty()) {
    throw JobRejected("a reference image measures one frame; a sequence cannot have one");
  }
  // The bundle and the scene path.
  Bundle bundle;
  try {
    bundle = protocol::bundle_from_wire(request.bundle());
    check_bundle_path(request.scene_path());
  } catch (const BundleError& e) {
    throw JobRejected(std::string("bad bundle: ") + e.what());
  }
  // A sequence whose scene's file name holds a frame pattern is a list of scene files, one still
  // scene per frame ("shots/frame_####.json"): every frame's file must be in the bundle.
  const bool list = frames && is_scene_list(request.scene_path());
  const auto frame_file = [&](int64_t frame) {
    try {
      return frame_scene_file(request.scene_path(), frame).generic_string();
    } catch (const std::invalid_argument& e) {
      throw JobRejected("scene " + request.scene_path() + ": " + e.what());
    }
  };
  std::set<std::string_view> in_bundle;
  for (const BundleFile& f : bundle.files) in_bundle.insert(f.path);
  for (int64_t i = 0; list && i < frames->count(); ++i) {
    const std::string file = frame_file(frames->at(i));
    if (!in_bundle.count(file)) {
      throw JobRejected(
          fmt::format("frame {}'s scene file '{}' is not in the bundle", frames->at(i), file));
    }
  }
  if (!list && !in_bundle.count(request.scene_path())) {
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
      std::optional<int64_t> frame =
          request.has_frame() ? std::optional<int64_t>(request.frame()) : std::nullopt;
      if (frames) frame = frames->first;
      if (list) {
        // The first and last frames' files: still scenes of one film.
        scene =
            load_scene(dir / frame_file(frames->first), check, SceneImages::kCheckOnly, {}, dir);
        const Scene last = frames->count() > 1 ? load_scene(dir / frame_file(frames->last), check,
                                                            SceneImages::kCheckOnly, {}, dir)
                                               : Scene{};
        for (const Scene* s : {static_cast<const Scene*>(&scene), &last}) {
          if (s->animation) {
            throw JobRejected(
                fmt::format("{} is animated: the files of a list are still scenes, one per frame",
                            frame_file(s == &scene ? frames->first : frames->last)));
          }
        }
        if (frames->count() > 1 && !protocol::same_settings(last.render, scene.render)) {
          throw JobRejected(fmt::format(
              "{}'s render settings differ from {}'s: the frames of a sequence share one set",
              frame_file(frames->last), frame_file(frames->first)));
        }
        if (frames->count() > 1 &&
            (last.film.width != scene.film.width || last.film.height != scene.film.height)) {
          throw JobRejected(
              fmt::format("{} is {}x{} but {} is {}x{}: the frames of a sequence share one film",
                          frame_file(frames->last), last.film.width, last.film.height,
                          frame_file(frames->first), scene.film.width, scene.film.height));
        }
        scene.frame = frames->first;
      } else {
        scene =
            load_scene(dir / request.scene_path(), check, SceneImages::kCheckOnly, {}, dir, frame);
        // A sequence: its last frame loads too (every frame between is checked by the workers).
        std::optional<Scene> last;
        if (frames && frames->count() > 1) {
          last = load_scene(dir / request.scene_path(), check, SceneImages::kCheckOnly, {}, dir,
                            frames->last);
        }
        // With an open shutter, those frames' poses at its ends load too (motion.h); a shutter
        // that cannot be is refused with the other settings below.
        RenderSettings shutter = scene.render;
        if (apply_shutter_overrides(request.overrides(), shutter) &&
            !shutter_problem(shutter.shutter_open, shutter.shutter_close, shutter.motion_steps)) {
          const auto check_ends = [&](const Scene& at) {
            check_shutter_ends(at, shutter, [&](double offset) {
              return load_scene_pose(dir / request.scene_path(), {}, dir, at.frame, offset);
            });
          };
          check_ends(scene);
          if (last) check_ends(*last);
        }
      }
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
  spec.frame = scene.frame;  // an animated scene's first frame when none was asked for
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
  if (o.has_roulette_depth()) spec.settings.roulette_depth = o.roulette_depth();
  try {
    if (o.sampler() != wire::SAMPLER_UNSPECIFIED)
      spec.settings.sampler = protocol::sampler_from_wire(o.sampler());
    if (o.roulette() != wire::ROULETTE_UNSPECIFIED)
      spec.settings.roulette = protocol::roulette_from_wire(o.roulette());
  } catch (const protocol::ProtocolError& e) {
    throw JobRejected(e.what());
  }
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
  if (spec.settings.max_depth > kMaxDepth && spec.settings.max_depth != kUnlimitedDepth) {
    throw JobRejected(fmt::format("max depth must be at most {} or unlimited ({}), got {}",
                                  kMaxDepth, kUnlimitedDepth, spec.settings.max_depth));
  }
  if (spec.settings.roulette_depth > kMaxRouletteDepth) {
    throw JobRejected(fmt::format("roulette depth must be at most {}, got {}", kMaxRouletteDepth,
                                  spec.settings.roulette_depth));
  }
  if (!apply_shutter_overrides(o, spec.settings))
    throw JobRejected("the shutter override needs both ends (open and close)");
  if (auto why = shutter_problem(spec.settings.shutter_open, spec.settings.shutter_close,
                                 spec.settings.motion_steps))
    throw JobRejected("motion blur: " + *why);
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
    if (scene.camera.full_width != 0)
      throw JobRejected("the scene's film is a crop of a larger image and cannot be resized");
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
  record.priority = request.priority();
  record.paused = request.paused();
  try {
    wire::Bundle canonical;
    protocol::bundle_to_wire(bundle, &canonical);
    store_.save_bundle(spec.id, canonical);
    if (spec.has_reference) store_.save_reference(spec.id, request.reference_exr());
    if (frames) {
      // The movie plays the frames rendered at the animation's speed.
      const double fps = (scene.animation ? scene.animation->fps : kGltfFps) / double(frames->step);
      prepared.frames = store_frames(spec, *frames, record, fps);
    } else {
      store_.save_record(record);  // throws: a job is accepted only once it is on disk
    }
    store_.sync_job_dir(spec.id);
  } catch (const std::exception& e) {
    fs::remove_all(store_.job_dir(spec.id), ec);
    throw JobRejected(storage_refusal(e, store_.root()));
  }
  prepared.spec = std::move(spec);
  prepared.priority = record.priority;
  prepared.paused = record.paused;
  prepared.warnings = scene.warnings;
  prepared.bundle_files = bundle.files.size();
  prepared.bundle_bytes = bundle.data_bytes();
  return prepared;
}

std::vector<JobSpec> JobManager::store_frames(const JobSpec& spec, const FrameList& frames,
                                              const JobRecord& shared, double fps) const {
  std::vector<JobSpec> out;
  try {
    for (int64_t i = 0; i < frames.count(); ++i) {
      JobRecord record = shared;
      record.paused = false;  // the sequence's pause, in its sequence.json, holds the frames
      JobSpec& f = record.spec;
      f.frame = frames.at(i);
      f.sequence = spec.id;
      // A list of scene files: the frame's own file.
      if (is_scene_list(spec.scene_path)) {
        f.frame_file = true;
        f.scene_path = frame_scene_file(spec.scene_path, *f.frame).generic_string();
      }
      f.id = JobStore::frame_id(spec.id, *f.frame);
      f.name = fmt::format("{} frame {}", spec.name, *f.frame);
      store_.create_job_dir(f.id);
      out.push_back(f);
      store_.save_record(record);
    }
    for (const JobSpec& f : out) store_.sync_job_dir(f.id);
    // Only now is the sequence whole: a crash before this line leaves frames that a restart
    // removes rather than a part of the sequence its client never heard of.
    SequenceRecord sequence;
    sequence.id = spec.id;
    sequence.frames = out.size();
    sequence.fps = fps;
    sequence.has_state = true;
    sequence.priority = shared.priority;
    sequence.paused = shared.paused;
    sequence.elapsed_seconds = 0.0;
    store_.mark_sequence_stored(sequence);
  } catch (...) {
    std::error_code ec;
    for (const JobSpec& f : out) fs::remove_all(store_.job_dir(f.id), ec);
    throw;
  }
  return out;
}

std::string JobManager::admit(PreparedJob prepared) {
  if (prepared.frames.empty()) {
    return admit_one(prepared.spec, std::move(prepared.reference), prepared.priority,
                     prepared.paused, prepared.warnings, prepared.bundle_files,
                     prepared.bundle_bytes);
  }
  // A sequence: a job per frame, in the scheduler's group of the sequence, which holds its
  // priority and pause.
  const std::string& id = prepared.spec.id;
  Sequence& q = sequences_[id];
  q.priority = prepared.priority;
  q.paused = prepared.paused;
  q.queued_unix_ms = prepared.spec.submitted_unix_ms;
  std::vector<std::string>& frames = q.frames;
  for (const JobSpec& f : prepared.frames) {
    try {
      frames.push_back(admit_one(f, std::nullopt, prepared.priority, /*paused=*/false,
                                 frames.empty() ? prepared.warnings : std::vector<std::string>{},
                                 prepared.bundle_files, prepared.bundle_bytes));
    } catch (const JobRejected&) {
      frames.push_back(f.id);  // recorded as failed, and listed with the sequence
    }
  }
  log_jobs()->info("sequence {} accepted: '{}', {} frames ({} to {})", id, prepared.spec.name,
                   frames.size(), *prepared.frames.front().frame, *prepared.frames.back().frame);
  return id;
}

std::string JobManager::admit_one(const JobSpec& spec, std::optional<Image> reference,
                                  int32_t priority, bool paused,
                                  const std::vector<std::string>& warnings, size_t bundle_files,
                                  uint64_t bundle_bytes) {
  const UnitGrid grid(spec.film, spec.tile_size, spec.settings.spp, spec.pass_spp);
  const std::string& hash = spec.bundle_hash;
  Job job;
  job.record.spec = spec;
  job.record.priority = priority;
  job.record.paused = paused;
  bundle_owner_.emplace(hash, JobStore::bundle_holder(spec));
  try {
    activate(job, std::move(reference));
  } catch (const std::exception& e) {
    // E.g. no memory for the job's film: it is on disk, so it is recorded as failed (and listed)
    // rather than tried again at every start.
    scheduler_.remove_job(spec.id);
    job.active.reset();
    job.record.state = wire::JOB_FAILED;
    job.record.paused = false;
    job.record.error = std::string("the master cannot hold the job: ") + e.what();
    job.record.stop_reason = stop_reason_name(StopReason::kFailed);
    job.record.finished_unix_ms = wall_ms();
    log_jobs()->error("job {}: {}", spec.id, job.record.error);
    const std::string error = job.record.error;
    auto [it, inserted] = jobs_.emplace(spec.id, std::move(job));
    save(it->second);
    throw JobRejected(error);
  }
  // A sequence's frames are logged once, as the sequence.
  log_jobs()->log(
      spec.sequence.empty() ? spdlog::level::info : spdlog::level::debug,
      "job {} accepted: '{}', scene {} {}x{}, {}, {}, max depth {}, seed {}; {} tiles of {} x "
      "{} passes of {} spp = {} units; bundle of {} files, {} ({}){}",
      spec.id, spec.name, spec.scene_path, spec.film.width, spec.film.height,
      describe_stop(spec.stop, spec.settings.spp), integrator_name(spec.settings.integrator),
      spec.settings.max_depth, spec.settings.seed, grid.tile_count(), spec.tile_size,
      grid.pass_count(), spec.pass_spp, grid.size(), bundle_files, human_bytes(bundle_bytes),
      hash.substr(0, 12), spec.has_reference ? "; error measured against its reference image" : "");
  for (const auto& w : warnings) log_jobs()->warn("job {}: {}", spec.id, w);
  note_accepted(job.record, grid.size(), describe_stop(spec.stop, spec.settings.spp), warnings);
  const std::string id = spec.id;
  jobs_.emplace(id, std::move(job));
  return id;
}

}  // namespace rayfarm::master
