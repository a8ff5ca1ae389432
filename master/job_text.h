#pragma once
// What the job manager's files (job_manager.h) share: their loggers and the few text helpers of
// their log lines and messages. Internal to master/.
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "common/util/log.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master::detail {

inline std::shared_ptr<spdlog::logger> log_jobs() { return get_logger("jobs"); }
inline std::shared_ptr<spdlog::logger> log_merger() { return get_logger("merger"); }
inline std::shared_ptr<spdlog::logger> log_scheduler() { return get_logger("scheduler"); }

inline bool is_active_state(wire::JobState s) {
  return s == wire::JOB_QUEUED || s == wire::JOB_RUNNING;
}

/// `text` with every `from` replaced by `to`.
inline std::string replace_all(std::string text, const std::string& from, const std::string& to) {
  if (from.empty()) return text;
  for (size_t pos = text.find(from); pos != std::string::npos;
       pos = text.find(from, pos + to.size())) {
    text.replace(pos, from.size(), to);
  }
  return text;
}

inline std::string human_bytes(uint64_t bytes) {
  if (bytes >= (uint64_t{1} << 20)) return fmt::format("{:.1f} MiB", bytes / 1048576.0);
  if (bytes >= 1024) return fmt::format("{:.1f} KiB", bytes / 1024.0);
  return fmt::format("{} B", bytes);
}

inline std::string human_rate(double samples_per_second) {
  if (samples_per_second >= 1e6) return fmt::format("{:.2f} Msamples/s", samples_per_second / 1e6);
  if (samples_per_second >= 1e3) return fmt::format("{:.1f} ksamples/s", samples_per_second / 1e3);
  return fmt::format("{:.0f} samples/s", samples_per_second);
}

}  // namespace rayfarm::master::detail
