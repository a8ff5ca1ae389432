#include "master/job_store.h"

#include "common/scene/motion.h"

#include "common/limits.h"
#include "common/util/atomic_file.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <system_error>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <nlohmann/json.hpp>

#include "common/protocol/convert.h"
#include "common/util/log.h"
#include "common/util/read_file.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// The inverse of protocol::job_state_name; JOB_STATE_UNSPECIFIED for anything else.
wire::JobState state_from_key(const std::string& s) {
  if (s == "queued") return wire::JOB_QUEUED;
  if (s == "running") return wire::JOB_RUNNING;
  if (s == "done") return wire::JOB_DONE;
  if (s == "failed") return wire::JOB_FAILED;
  if (s == "cancelled") return wire::JOB_CANCELLED;
  return wire::JOB_STATE_UNSPECIFIED;
}

/// A figure for job.json: JSON has no NaN or infinity (nlohmann writes them as null), so a
/// non-finite figure is written as the record's "unknown" value.
double finite_or(double value, double unknown) { return std::isfinite(value) ? value : unknown; }

/// A number of job.json: `fallback` when absent or null (an unknown figure), else it must be a
/// number; throws naming the key otherwise.
double number_or(const json& j, const char* key, double fallback) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return fallback;
  if (!it->is_number()) throw std::runtime_error(std::string("\"") + key + "\" is not a number");
  const double v = it->get<double>();
  return std::isfinite(v) ? v : fallback;
}

/// A job's log as [[unix_ms, "level", "text"], ...].
json log_json(const JobLog& log) {
  json lines = json::array();
  for (const JobLogLine& l : log.lines) lines.push_back(json::array({l.unix_ms, l.level, l.text}));
  return lines;
}

JobLog log_from_json(const json& j) {
  // A longer log than this master keeps (an edited file) keeps its latest lines.
  if (!j.is_array() || j.size() > 100 * JobLog::kMaxLines)
    throw std::runtime_error("malformed log");
  JobLog log;
  for (const json& line : j) {
    if (!line.is_array() || line.size() != 3 || !line[0].is_number_integer() ||
        !line[1].is_string() || !line[2].is_string()) {
      throw std::runtime_error("malformed log line");
    }
    log.add(line[0].get<int64_t>(), line[1].get<std::string>(), line[2].get<std::string>());
  }
  log.version = 0;  // as on disk
  return log;
}

json to_json(const JobRecord& r) {
  const JobSpec& s = r.spec;
  return json{{"id", s.id},
              {"name", s.name},
              {"bundle_hash", s.bundle_hash},
              {"scene_path", s.scene_path},
              {"spp", s.settings.spp},
              {"max_depth", s.settings.max_depth},
              {"integrator", integrator_name(s.settings.integrator)},
              {"seed", s.settings.seed},
              {"clamp", finite_or(s.settings.clamp, 0.0)},
              {"sampler", sampler_name(s.settings.sampler)},
              {"roulette", roulette_name(s.settings.roulette)},
              {"roulette_depth", s.settings.roulette_depth},
              {"shutter",
               {finite_or(s.settings.shutter_open, 0.0), finite_or(s.settings.shutter_close, 0.0)}},
              {"motion_steps", s.settings.motion_steps},
              {"width", s.film.width},
              {"height", s.film.height},
              {"tile_size", s.tile_size},
              {"pass_spp", s.pass_spp},
              {"target_error", finite_or(s.stop.target_error, 0.0)},
              {"time_limit_s", finite_or(s.stop.time_limit_s, 0.0)},
              {"adaptive", s.stop.adaptive},
              {"min_passes", s.stop.min_passes},
              {"has_reference", s.has_reference},
              {"submitted_unix_ms", s.submitted_unix_ms},
              {"owner", s.owner},
              {"state", protocol::job_state_name(r.state)},
              {"priority", r.priority},
              {"paused", r.paused},
              {"queued_unix_ms", r.queued_unix_ms},
              {"started_unix_ms", r.started_unix_ms},
              {"finished_unix_ms", r.finished_unix_ms},
              {"log", log_json(r.log)},
              {"log_left_out", r.log.left_out},
              {"error", r.error},
              {"elapsed_seconds", finite_or(r.elapsed_seconds, 0.0)},
              {"stop_reason", r.stop_reason},
              {"units_done", r.units_done},
              {"passes_done", r.passes_done},
              {"spp_min", r.spp_min},
              {"spp_mean", finite_or(r.spp_mean, 0.0)},
              {"tiles_converged", r.tiles_converged},
              {"est_rel_mse", finite_or(r.est_rel_mse, -1.0)},
              {"ref_rel_mse", finite_or(r.ref_rel_mse, -1.0)},
              {"frame", s.frame ? json(*s.frame) : json(nullptr)},
              {"sequence", s.sequence},
              {"frame_file", s.frame_file}};
}

JobRecord from_json(const json& j) {
  JobRecord r;
  JobSpec& s = r.spec;
  s.id = j.at("id").get<std::string>();
  s.name = j.at("name").get<std::string>();
  s.bundle_hash = j.at("bundle_hash").get<std::string>();
  s.scene_path = j.at("scene_path").get<std::string>();
  s.settings.spp = j.at("spp").get<uint32_t>();
  s.settings.max_depth = j.at("max_depth").get<uint32_t>();
  const auto integrator = parse_integrator(j.at("integrator").get<std::string>());
  if (!integrator) throw std::runtime_error("unknown integrator");
  s.settings.integrator = *integrator;
  s.settings.seed = j.at("seed").get<uint64_t>();
  s.settings.clamp = static_cast<float>(number_or(j, "clamp", 0.0));
  if (!(s.settings.clamp >= 0)) throw std::runtime_error("negative clamp");
  // Jobs stored before the sampler and the roulette rule were settings rendered with the
  // independent stream and the update rule: they resume with those (the light sampling of the
  // renderer that resumes them may still differ; every estimator is unbiased).
  const auto sampler = parse_sampler(j.value("sampler", std::string("independent")));
  if (!sampler) throw std::runtime_error("unknown sampler");
  s.settings.sampler = *sampler;
  const auto roulette = parse_roulette(j.value("roulette", std::string("update")));
  if (!roulette) throw std::runtime_error("unknown roulette");
  s.settings.roulette = *roulette;
  s.settings.roulette_depth = j.value("roulette_depth", 0u);
  // Jobs stored before motion blur had the shutter closed.
  if (auto it = j.find("shutter"); it != j.end()) {
    if (!it->is_array() || it->size() != 2) throw std::runtime_error("malformed shutter");
    s.settings.shutter_open = (*it)[0].get<float>();
    s.settings.shutter_close = (*it)[1].get<float>();
  }
  const int64_t steps = j.value("motion_steps", int64_t{kDefaultMotionSteps});
  if (steps < kMinMotionSteps || steps > kMaxMotionSteps)
    throw std::runtime_error("motion_steps out of range");
  s.settings.motion_steps = static_cast<uint32_t>(steps);
  if (auto why = shutter_problem(s.settings.shutter_open, s.settings.shutter_close,
                                 s.settings.motion_steps))
    throw std::runtime_error(*why);
  if ((s.settings.max_depth > kMaxDepth && s.settings.max_depth != kUnlimitedDepth) ||
      s.settings.roulette_depth > kMaxRouletteDepth || s.settings.spp == 0 ||
      s.settings.spp > kMaxSpp) {
    throw std::runtime_error("render settings out of range");
  }
  s.film.width = j.at("width").get<uint32_t>();
  s.film.height = j.at("height").get<uint32_t>();
  s.tile_size = j.at("tile_size").get<uint32_t>();
  s.pass_spp = j.at("pass_spp").get<uint32_t>();
  s.stop.target_error = number_or(j, "target_error", 0.0);
  s.stop.time_limit_s = number_or(j, "time_limit_s", 0.0);
  s.stop.adaptive = j.value("adaptive", true);
  s.stop.min_passes = j.value("min_passes", 0u);
  s.has_reference = j.value("has_reference", false);
  s.submitted_unix_ms = j.at("submitted_unix_ms").get<int64_t>();
  s.owner = j.value("owner", "");
  // Records from before animation have no frame: a still.
  if (const auto f = j.find("frame"); f != j.end() && !f->is_null()) {
    if (!f->is_number_integer()) throw std::runtime_error("frame is not an integer");
    const bool in_range = f->is_number_unsigned() ? f->get<uint64_t>() <= uint64_t(kMaxFrameNumber)
                                                  : f->get<int64_t>() >= -kMaxFrameNumber &&
                                                        f->get<int64_t>() <= kMaxFrameNumber;
    if (!in_range) throw std::runtime_error("frame out of range");
    s.frame = f->get<int64_t>();
  }
  s.sequence = j.value("sequence", "");
  s.frame_file = j.value("frame_file", false);
  if (s.frame_file && s.sequence.empty()) throw std::runtime_error("frame_file outside a sequence");
  if (!s.sequence.empty() && (!s.frame || s.id != JobStore::frame_id(s.sequence, *s.frame))) {
    throw std::runtime_error("sequence does not match the id and frame");
  }
  const std::string state = j.at("state").get<std::string>();
  r.state = state_from_key(state);
  if (r.state == wire::JOB_STATE_UNSPECIFIED)
    throw std::runtime_error("unknown state \"" + state + "\"");
  // Records from before priorities: 0, not paused. Read exactly: a value past int32's range must
  // fail the check, not wrap into it.
  if (const auto p = j.find("priority"); p != j.end()) {
    if (!p->is_number_integer()) throw std::runtime_error("priority is not an integer");
    const bool in_range = p->is_number_unsigned() ? p->get<uint64_t>() <= uint64_t{kMaxPriority}
                                                  : p->get<int64_t>() >= kMinPriority &&
                                                        p->get<int64_t>() <= kMaxPriority;
    if (!in_range) throw std::runtime_error("priority out of range");
    r.priority = p->get<int32_t>();
  }
  if (const auto p = j.find("paused"); p != j.end()) {
    if (!p->is_boolean()) throw std::runtime_error("paused is not true or false");
    // Only a queued or running job can be paused: an ended one reads as not paused.
    r.paused = p->get<bool>() && (r.state == wire::JOB_QUEUED || r.state == wire::JOB_RUNNING);
  }
  r.queued_unix_ms = j.value("queued_unix_ms", int64_t{0});
  // Records from before job times and logs have neither.
  r.started_unix_ms = j.value("started_unix_ms", int64_t{0});
  r.finished_unix_ms = j.value("finished_unix_ms", int64_t{0});
  if (const auto log = j.find("log"); log != j.end()) r.log = log_from_json(*log);
  r.log.left_out = j.value("log_left_out", 0u);
  r.error = j.value("error", "");
  r.elapsed_seconds = number_or(j, "elapsed_seconds", 0.0);
  r.stop_reason = j.value("stop_reason", "");
  r.units_done = j.value("units_done", uint64_t{0});
  r.passes_done = j.value("passes_done", 0u);
  r.spp_min = j.value("spp_min", 0u);
  r.spp_mean = number_or(j, "spp_mean", 0.0);
  r.tiles_converged = j.value("tiles_converged", 0u);
  r.est_rel_mse = number_or(j, "est_rel_mse", -1.0);
  r.ref_rel_mse = number_or(j, "ref_rel_mse", -1.0);
  if (!(s.stop.target_error >= 0) || !(s.stop.time_limit_s >= 0)) {
    throw std::runtime_error("negative target error or time limit");
  }
  if (s.settings.spp == 0 || s.tile_size == 0 || s.pass_spp == 0 || s.film.width == 0 ||
      s.film.height == 0) {
    throw std::runtime_error("zero size, spp, tile or pass");
  }
  return r;
}

/// The record of a job whose job.json cannot be read: its folder's name and what is wrong.
JobRecord unreadable_record(const std::string& id, const fs::path& file, const std::string& why) {
  JobRecord r;
  r.spec.id = id;
  r.spec.name = "(unreadable record)";
  r.state = wire::JOB_STATE_UNSPECIFIED;
  r.error = fmt::format("the master cannot read {}: {}", file.string(), why);
  r.unreadable = true;
  return r;
}

/// The number in a job id "j0042" (or a frame's "j0042.0012"), or 0 when it is not one.
uint64_t id_number(const std::string& id) {
  if (id.size() < 2 || id[0] != 'j') return 0;
  uint64_t n = 0;
  for (size_t i = 1; i < id.size(); ++i) {
    if (id[i] == '.' && i > 1) break;
    if (id[i] < '0' || id[i] > '9' || n > (uint64_t{1} << 40)) return 0;
    n = n * 10 + static_cast<uint64_t>(id[i] - '0');
  }
  return n;
}

}  // namespace

JobStore::JobStore(fs::path data_dir) : root_(std::move(data_dir)) {
  std::error_code ec;
  fs::create_directories(root_ / "jobs", ec);
  if (!ec) {
    fs::remove_all(root_ / "tmp", ec);
    ec.clear();
    fs::create_directories(root_ / "tmp", ec);
  }
  if (ec) throw std::runtime_error("cannot use data dir " + root_.string() + ": " + ec.message());
  for (const auto& entry : fs::directory_iterator(root_ / "jobs", ec)) {
    next_id_ = std::max(next_id_, id_number(entry.path().filename().string()) + 1);
  }
}

fs::path JobStore::job_dir(const std::string& id) const { return root_ / "jobs" / id; }

std::string JobStore::allocate_id() {
  std::lock_guard lock(mutex_);
  for (;; ++next_id_) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "j%04llu", static_cast<unsigned long long>(next_id_));
    std::error_code ec;
    if (fs::create_directory(job_dir(buf), ec) && !ec) {
      ++next_id_;
      return buf;
    }
    if (ec)
      throw std::runtime_error("cannot create " + job_dir(buf).string() + ": " + ec.message());
  }
}

std::string JobStore::frame_id(const std::string& sequence, int64_t frame) {
  return fmt::format("{}.{:04d}", sequence, frame);
}

void JobStore::create_job_dir(const std::string& id) {
  std::error_code ec;
  if (!fs::create_directory(job_dir(id), ec) || ec) {
    throw std::runtime_error("cannot create " + job_dir(id).string() + ": " +
                             (ec ? ec.message() : std::string("it exists")));
  }
}

namespace {

json sequence_json(const SequenceRecord& r) {
  return json{{"id", r.id},
              {"frames", r.frames},
              {"fps", finite_or(r.fps, 24.0)},
              {"priority", r.priority},
              {"paused", r.paused},
              {"cancelled_unix_ms", r.cancelled_unix_ms},
              {"elapsed_seconds", finite_or(r.elapsed_seconds, -1.0)}};
}

}  // namespace

void JobStore::mark_sequence_stored(const SequenceRecord& record) {
  save_sequence(record);
  sync_job_dir(record.id);
}

void JobStore::save_sequence(const SequenceRecord& record) {
  write_file_atomically(job_dir(record.id) / "sequence.json",
                        sequence_json(record).dump() + "\n");
}

SequenceRecord JobStore::load_sequence(const std::string& id) const {
  SequenceRecord r;
  r.id = id;
  try {
    std::ifstream in(job_dir(id) / "sequence.json");
    const json j = json::parse(in);
    r.frames = j.value("frames", size_t{0});
    const double fps = number_or(j, "fps", 24.0);
    if (fps > 0 && fps <= 1000) r.fps = fps;
    if (j.contains("priority")) {
      r.has_state = true;
      r.priority = std::clamp(j.at("priority").get<int32_t>(), kMinPriority, kMaxPriority);
      r.paused = j.value("paused", false);
    }
    r.cancelled_unix_ms = j.value("cancelled_unix_ms", int64_t{0});
    r.elapsed_seconds = number_or(j, "elapsed_seconds", -1.0);
  } catch (const std::exception& e) {
    get_logger("master")->error("cannot read the state of sequence {} ({}): its frames' "
                                "records are used",
                                id, e.what());
  }
  return r;
}

double JobStore::sequence_fps(const std::string& id) const {
  return load_sequence(id).fps;
}

bool JobStore::sequence_stored(const std::string& id) const {
  std::error_code ec;
  return fs::exists(job_dir(id) / "sequence.json", ec);
}

fs::path JobStore::make_scratch_dir() {
  fs::path dir;
  {
    std::lock_guard lock(mutex_);
    dir = root_ / "tmp" / fmt::format("s{}", ++scratch_counter_);
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create " + dir.string() + ": " + ec.message());
  return dir;
}

void JobStore::save_record(const JobRecord& record) {
  if (record.unreadable) {
    throw std::logic_error("job " + record.spec.id + ": an unreadable record is never saved over");
  }
  write_file_atomically(job_dir(record.spec.id) / "job.json", to_json(record).dump(2) + "\n");
}

void JobStore::sync_job_dir(const std::string& id) {
  for (const fs::path& dir : {job_dir(id), root_ / "jobs"}) sync_folder(dir);
}

void JobStore::save_bundle(const std::string& id, const wire::Bundle& bundle) {
  std::string bytes;
  if (!bundle.SerializeToString(&bytes))
    throw std::runtime_error("cannot serialize bundle of " + id);
  write_file_atomically(job_dir(id) / "bundle.pb", bytes);
}

void JobStore::save_reference(const std::string& id, const std::string& exr_bytes) {
  write_file_atomically(reference_path(id), exr_bytes);
}

std::optional<wire::Bundle> JobStore::load_bundle(const std::string& id) const {
  auto bytes = try_read_whole_file(job_dir(id) / "bundle.pb");
  if (!bytes) return std::nullopt;
  wire::Bundle bundle;
  if (!bundle.ParseFromString(*bytes)) return std::nullopt;
  return bundle;
}

std::optional<std::string> JobStore::read_file(const std::string& id,
                                               const std::string& name) const {
  return try_read_whole_file(job_dir(id) / name);
}

std::vector<JobRecord> JobStore::load_records() const {
  std::vector<JobRecord> records;
  std::error_code ec;
  std::vector<fs::path> dirs;
  for (const auto& entry : fs::directory_iterator(root_ / "jobs", ec)) dirs.push_back(entry.path());
  std::sort(dirs.begin(), dirs.end());
  for (const auto& dir : dirs) {
    const fs::path file = dir / "job.json";
    auto text = try_read_whole_file(file);
    if (!text) continue;  // a job dir whose record was never written: a submit that failed
    try {
      JobRecord r = from_json(json::parse(*text));
      if (r.spec.id != dir.filename().string())
        throw std::runtime_error("id does not match its folder");
      records.push_back(std::move(r));
    } catch (const std::exception& e) {
      // Kept, as a record that says what is wrong: `rayfarm list` shows it, `rayfarm rm` removes
      // it.
      get_logger("master")->error("cannot read {}: {}; the job is listed as unreadable",
                                  file.string(), e.what());
      records.push_back(unreadable_record(dir.filename().string(), file, e.what()));
    }
  }
  return records;
}

}  // namespace rayfarm::master
