#pragma once
// What the job manager's files (job_manager.h) share: their loggers and the few text helpers of
// their log lines and messages (byte sizes and rates: common/util/text.h). Internal to master/.
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "common/util/log.h"
#include "common/util/text.h"
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

}  // namespace rayfarm::master::detail
