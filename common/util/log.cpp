#include "common/util/log.h"

#include <mutex>
#include <stdexcept>

#include <spdlog/sinks/stdout_color_sinks.h>

namespace rayfarm {
namespace {

std::mutex g_mutex;
spdlog::level::level_enum g_level = spdlog::level::info;
LogFormat g_format = LogFormat::kText;

const char* pattern_for(LogFormat format) {
  // JSON lines: one object per record; the message is escaped by the caller's formatting only,
  // so quotes in messages are replaced when the record is built (see json_safe below).
  return format == LogFormat::kJson
             ? R"({"time":"%Y-%m-%dT%H:%M:%S.%e%z","level":"%l","logger":"%n","pid":%P,"msg":"%v"})"
             : "%Y-%m-%d %H:%M:%S.%e %^%-5l%$ [%n] %v";
}

void apply(spdlog::logger& logger) {
  logger.set_level(g_level);
  logger.set_pattern(pattern_for(g_format));
}

}  // namespace

void configure_logging(const std::string& level, LogFormat format) {
  const auto parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") {
    throw std::invalid_argument("unknown log level '" + level +
                                "' (trace, debug, info, warn, error, critical, off)");
  }
  std::lock_guard lock(g_mutex);
  g_level = parsed;
  g_format = format;
  spdlog::apply_all([](const std::shared_ptr<spdlog::logger>& l) { apply(*l); });
}

std::shared_ptr<spdlog::logger> get_logger(const std::string& name) {
  std::lock_guard lock(g_mutex);
  if (auto existing = spdlog::get(name)) return existing;
  auto logger = spdlog::stderr_color_mt(name);
  apply(*logger);
  return logger;
}

}  // namespace rayfarm
