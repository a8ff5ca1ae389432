#pragma once
// One named spdlog logger per component ("master", "worker", "scheduler", "render", ...).
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

namespace rayfarm {

enum class LogFormat { kText, kJson };

/// Sets the level ("trace".."off") and format of every logger, present and future. Logs go to
/// stderr. Throws std::invalid_argument on an unknown level.
void configure_logging(const std::string& level, LogFormat format = LogFormat::kText);

/// The logger named `name`, created on first use with the configured level and format.
std::shared_ptr<spdlog::logger> get_logger(const std::string& name);

}  // namespace rayfarm
