#include "cli/farm_output.h"

#include <cmath>
#include <ctime>
#include <iostream>

#include <fmt/chrono.h>
#include <fmt/format.h>

#include "common/protocol/convert.h"
#include "common/scene/scene.h"
#include "common/util/text.h"

namespace rayfarm::cli {
namespace protocol = rayfarm::protocol;

namespace {

/// A sequence frame's state, "paused" for one held before it is done.
const char* frame_state_label(const wire::SequenceFrame& f) {
  return f.paused() && f.state() != wire::JOB_DONE ? "paused" : protocol::job_state_name(f.state());
}

/// A sequence's frames (status of a sequence only): frame, job, state, percent.
nlohmann::json frames_json(const wire::JobStatus& st) {
  nlohmann::json out = nlohmann::json::array();
  for (const wire::SequenceFrame& f : st.frames()) {
    out.push_back({{"frame", f.frame()},
                   {"job", f.job_id()},
                   {"state", frame_state_label(f)},
                   {"percent", f.percent()}});
  }
  return out;
}

double percent(const wire::JobStatus& st) {
  return st.units_total()
             ? 100.0 * static_cast<double>(st.units_done()) / static_cast<double>(st.units_total())
             : 0.0;
}

const char* integrator_label(wire::Integrator value) {
  try {
    return integrator_name(protocol::integrator_from_wire(value));
  } catch (const protocol::ProtocolError&) {
    return "unknown integrator";
  }
}

const char* sampler_label(wire::Sampler value) {
  try {
    return sampler_name(protocol::sampler_from_wire(value));
  } catch (const protocol::ProtocolError&) {
    return "unknown sampler";
  }
}

const char* roulette_label(wire::Roulette value) {
  try {
    return roulette_name(protocol::roulette_from_wire(value));
  } catch (const protocol::ProtocolError&) {
    return "unknown roulette";
  }
}

/// A time for JSON: Unix milliseconds, null when not yet (0).
nlohmann::json unix_ms(int64_t ms) { return ms > 0 ? nlohmann::json(ms) : nlohmann::json(nullptr); }

/// A figure for JSON: null when unknown (negative or not finite).
nlohmann::json figure(double value) {
  return std::isfinite(value) && value >= 0 ? nlohmann::json(value) : nlohmann::json(nullptr);
}

}  // namespace

std::string format_duration(double seconds) {
  if (seconds < 0) return "?";
  if (seconds < 60) return fmt::format("{:.1f} s", seconds);
  if (seconds < 3600)
    return fmt::format("{}m{:02}s", static_cast<int>(seconds) / 60, static_cast<int>(seconds) % 60);
  return fmt::format("{}h{:02}m", static_cast<int>(seconds) / 3600,
                     (static_cast<int>(seconds) / 60) % 60);
}

bool finished(wire::JobState state) {
  // JOB_STATE_UNSPECIFIED: a job whose record the master cannot read; it will not change.
  return state == wire::JOB_DONE || state == wire::JOB_FAILED || state == wire::JOB_CANCELLED ||
         state == wire::JOB_STATE_UNSPECIFIED;
}

nlohmann::json status_json(const wire::JobStatus& st) {
  return nlohmann::json{
      {"job", st.job_id()},
      {"name", st.name()},
      {"owner", st.owner()},
      {"state", protocol::job_state_name(st.state())},
      {"paused", st.paused()},
      {"priority", st.priority()},
      {"frame", st.has_frame() ? nlohmann::json(st.frame()) : nlohmann::json(nullptr)},
      {"sequence", st.sequence().empty() ? nlohmann::json(nullptr) : nlohmann::json(st.sequence())},
      {"frames_total", st.frames_total()},
      {"frames_done", st.frames_done()},
      {"frames", frames_json(st)},
      {"previews", st.previews().empty() ? nlohmann::json(nullptr) : nlohmann::json(st.previews())},
      {"storage_error",
       st.storage_error().empty() ? nlohmann::json(nullptr) : nlohmann::json(st.storage_error())},
      {"error", st.error().empty() ? nlohmann::json(nullptr) : nlohmann::json(st.error())},
      {"stop_reason",
       st.stop_reason().empty() ? nlohmann::json(nullptr) : nlohmann::json(st.stop_reason())},
      {"width", st.width()},
      {"height", st.height()},
      {"spp", st.settings().spp()},
      {"integrator", st.state() == wire::JOB_STATE_UNSPECIFIED
                         ? nlohmann::json(nullptr)
                         : nlohmann::json(integrator_label(st.settings().integrator()))},
      {"max_depth", st.settings().max_depth() == kUnlimitedDepth
                        ? nlohmann::json("unlimited")
                        : nlohmann::json(st.settings().max_depth())},
      {"sampler", st.state() == wire::JOB_STATE_UNSPECIFIED
                      ? nlohmann::json(nullptr)
                      : nlohmann::json(sampler_label(st.settings().sampler()))},
      {"roulette", st.state() == wire::JOB_STATE_UNSPECIFIED
                       ? nlohmann::json(nullptr)
                       : nlohmann::json(roulette_label(st.settings().roulette()))},
      {"roulette_depth", st.settings().roulette_depth()},
      {"shutter", {st.settings().shutter_open(), st.settings().shutter_close()}},
      {"motion_steps", st.settings().motion_steps()},
      {"seed", st.settings().seed()},
      {"clamp", st.settings().clamp()},
      {"tile_size", st.tile_size()},
      {"pass_spp", st.pass_spp()},
      {"passes_done", st.passes_done()},
      {"passes_total", st.passes_total()},
      {"units_done", st.units_done()},
      {"units_total", st.units_total()},
      {"units_leased", st.units_leased()},
      {"percent", percent(st)},
      {"spp_done", st.spp_done()},
      {"spp_mean", st.spp_mean()},
      {"est_rel_mse", figure(st.est_rel_mse())},
      {"ref_rel_mse", figure(st.ref_rel_mse())},
      {"tiles_converged", st.tiles_converged()},
      {"tiles_total", st.tiles_total()},
      {"samples_per_second", st.samples_per_second()},
      {"elapsed_seconds", st.elapsed_seconds()},
      {"eta_seconds", figure(st.eta_seconds())},
      {"workers_busy", st.workers_busy()},
      {"workers_total", st.workers_total()},
      {"submitted_unix_ms", unix_ms(st.submitted_unix_ms())},
      {"started_unix_ms", unix_ms(st.started_unix_ms())},
      {"finished_unix_ms", unix_ms(st.finished_unix_ms())}};
}

std::string format_time(int64_t unix_ms) {
  if (unix_ms <= 0) return "-";
  const std::time_t t = static_cast<std::time_t>(unix_ms / 1000);
  std::tm local{};
  if (localtime_r(&t, &local) == nullptr) return "?";
  return fmt::format("{:%Y-%m-%d %H:%M:%S}", local);
}

std::string state_label(const wire::JobStatus& st) {
  return st.paused() && !finished(st.state()) ? "paused" : protocol::job_state_name(st.state());
}

void print_json(const nlohmann::json& j) { std::cout << j.dump() << "\n" << std::flush; }

std::string progress_line(const wire::JobStatus& st) {
  std::string line = st.frames_total() > 0
                         ? fmt::format("{} {:<9} frames {}/{}{}  {:5.1f}%", st.job_id(),
                                       state_label(st), st.frames_done(), st.frames_total(),
                                       st.has_frame() && !finished(st.state())
                                           ? fmt::format(" (frame {})", st.frame())
                                           : std::string(),
                                       percent(st))
                         : fmt::format("{} {:<9} pass {}/{}  {}/{} spp  {:5.1f}%", st.job_id(),
                                       state_label(st), st.passes_done(), st.passes_total(),
                                       st.spp_done(), st.settings().spp(), percent(st));
  if (st.spp_mean() >= st.spp_done() + 1.0) line += fmt::format(" (mean {:.0f})", st.spp_mean());
  if (st.est_rel_mse() >= 0) line += fmt::format("  relMSE {:.3g}", st.est_rel_mse());
  if (st.ref_rel_mse() >= 0) line += fmt::format(" (measured {:.3g})", st.ref_rel_mse());
  if (st.state() == wire::JOB_RUNNING && !st.paused()) {
    line += fmt::format("  {}  ETA {}  workers {} busy/{}", human_rate(st.samples_per_second()),
                        format_duration(st.eta_seconds()), st.workers_busy(), st.workers_total());
  } else if (st.state() == wire::JOB_DONE) {
    // A sequence has no stop rule of its own: each frame stopped by its own.
    line += fmt::format("  in {}{}", format_duration(st.elapsed_seconds()),
                        st.stop_reason().empty() ? "" : " (" + st.stop_reason() + ")");
  }
  if (!st.storage_error().empty()) line += "  storage: " + st.storage_error();
  return line;
}

void print_status(const wire::JobStatus& st) {
  std::cout << fmt::format("job        {} ({})\n", st.job_id(), st.name());
  if (st.frames_total() > 0) {
    std::cout << fmt::format("frames     {}/{} done{}\n", st.frames_done(), st.frames_total(),
                             st.has_frame() ? fmt::format(", frame {} next", st.frame()) : "");
    if (!st.previews().empty()) std::cout << fmt::format("previews   {}\n", st.previews());
  } else if (st.has_frame()) {
    std::cout << fmt::format("frame      {}{}\n", st.frame(),
                             st.sequence().empty() ? "" : " of sequence " + st.sequence());
  }
  std::cout << fmt::format(
      "state      {}{}\n", state_label(st),
      finished(st.state()) ? std::string() : fmt::format(", priority {}", st.priority()));
  if (!st.owner().empty()) std::cout << fmt::format("owner      key '{}'\n", st.owner());
  if (!st.storage_error().empty()) {
    // The master cannot write the job's image, checkpoint or record (a full disk): it says why.
    std::cout << fmt::format("storage    {}\n", st.storage_error());
  }
  if (!st.error().empty()) {
    // Why it failed; for a cancelled job, who cancelled it.
    std::cout << fmt::format("{:<10} {}\n",
                             st.state() == wire::JOB_CANCELLED ? "cancelled" : "error", st.error());
  }
  if (st.state() == wire::JOB_STATE_UNSPECIFIED) return;  // nothing else is known
  std::cout << fmt::format(
      "image      {}x{}, {} spp, {}, max depth {}, seed {}, {} sampler{}\n", st.width(),
      st.height(), st.settings().spp(), integrator_label(st.settings().integrator()),
      depth_name(st.settings().max_depth()), st.settings().seed(),
      sampler_label(st.settings().sampler()),
      st.settings().clamp() > 0 ? fmt::format(", clamp {:g} (biased)", st.settings().clamp()) : "");
  std::cout << fmt::format(
      "work       tiles of {} px, passes of {} spp: {}/{} units ({:.1f}%), {} leased\n",
      st.tile_size(), st.pass_spp(), st.units_done(), st.units_total(), percent(st),
      st.units_leased());
  std::cout << fmt::format("progress   pass {}/{}, {}/{} spp, {:.1f} spp mean\n", st.passes_done(),
                           st.passes_total(), st.spp_done(), st.settings().spp(), st.spp_mean());
  if (st.est_rel_mse() >= 0 || st.ref_rel_mse() >= 0) {
    std::cout << fmt::format(
        "relMSE     estimated {}{}\n",
        st.est_rel_mse() >= 0 ? fmt::format("{:.4g}", st.est_rel_mse()) : "unknown",
        st.ref_rel_mse() >= 0
            ? fmt::format(", measured against the reference {:.4g}", st.ref_rel_mse())
            : "");
  }
  if (st.tiles_converged() > 0) {
    std::cout << fmt::format("tiles      {}/{} converged\n", st.tiles_converged(),
                             st.tiles_total());
  }
  if (!st.stop_reason().empty()) std::cout << fmt::format("stopped    {}\n", st.stop_reason());
  // An ETA only while there is something to wait for: a job over, or paused, has none.
  const bool waiting = st.state() == wire::JOB_RUNNING || st.state() == wire::JOB_QUEUED;
  std::cout << fmt::format("time       {} elapsed{}, {}\n", format_duration(st.elapsed_seconds()),
                           waiting && !st.paused()
                               ? ", ETA " + format_duration(st.eta_seconds())
                               : std::string(finished(st.state()) ? "" : ", no ETA (paused)"),
                           human_rate(st.samples_per_second()));
  std::cout << fmt::format("workers    {} busy on this job, {} connected\n", st.workers_busy(),
                           st.workers_total());
  // When it was submitted, started (its first unit since it was last queued) and ended.
  if (st.submitted_unix_ms() > 0) {
    std::cout << fmt::format(
        "submitted  {}{}{}\n", format_time(st.submitted_unix_ms()),
        st.started_unix_ms() > 0 ? ", started " + format_time(st.started_unix_ms()) : std::string(),
        st.finished_unix_ms() > 0 ? ", ended " + format_time(st.finished_unix_ms())
                                  : std::string());
  }
  if (st.frames_size() > 0) {
    std::cout << fmt::format("\n{:>8} {:<16} {:<9} {:>7}\n", "FRAME", "JOB", "STATE", "DONE");
    for (const wire::SequenceFrame& f : st.frames()) {
      std::cout << fmt::format("{:>8} {:<16} {:<9} {:>6.1f}%\n", f.frame(), f.job_id(),
                               frame_state_label(f), f.percent());
    }
  }
}

void print_table(const wire::JobList& list) {
  if (list.jobs().empty()) {
    std::cout << "no jobs\n";
    return;
  }
  std::cout << fmt::format("{:<8} {:<24} {:<12} {:<9} {:>4} {:>7} {:>11} {:>11} {:>10}\n", "JOB",
                           "NAME", "OWNER", "STATE", "PRI", "DONE", "SPP", "SIZE", "ELAPSED");
  for (const auto& st : list.jobs()) {
    std::cout << fmt::format(
        "{:<8} {:<24} {:<12} {:<9} {:>4} {:>6.1f}% {:>11} {:>11} {:>10}\n", st.job_id(),
        st.name().substr(0, 24), st.owner().empty() ? "-" : st.owner().substr(0, 12),
        state_label(st), finished(st.state()) ? std::string("-") : std::to_string(st.priority()),
        percent(st),
        st.frames_total() > 0 ? fmt::format("{}/{} fr", st.frames_done(), st.frames_total())
                              : fmt::format("{}/{}", st.spp_done(), st.settings().spp()),
        fmt::format("{}x{}", st.width(), st.height()), format_duration(st.elapsed_seconds()));
  }
  for (const auto& st : list.jobs()) {
    if (st.state() == wire::JOB_STATE_UNSPECIFIED) {
      std::cout << fmt::format("{}: {}\n", st.job_id(), st.error());
    }
  }
}

nlohmann::json worker_json(const wire::WorkerInfo& w) {
  return nlohmann::json{
      {"id", w.id()},
      {"name", w.name()},
      {"key_name", w.key_name().empty() ? nlohmann::json(nullptr) : nlohmann::json(w.key_name())},
      {"state", worker_state(w)},
      {"control", w.control().empty() ? "enabled" : w.control()},
      {"threads", w.threads()},
      {"units", w.units()},
      {"units_done", w.units_done()},
      {"samples_per_second", w.samples_per_second()},
      {"last_seen_seconds", w.last_seen_seconds()},
      {"build", w.build()}};
}

}  // namespace rayfarm::cli
