#pragma once
// The --log-level and --log-format options that every rayfarm executable takes.
#include <string>

#include <CLI/CLI.hpp>

#include "common/util/log.h"

namespace rayfarm {

struct LoggingOptions {
  std::string level = "info";
  std::string format = "text";

  /// Configures every logger with these options.
  void apply() const {
    configure_logging(level, format == "json" ? LogFormat::kJson : LogFormat::kText);
  }
};

/// Adds --log-level and --log-format to `app`, bound to `options`; bad values are parse errors.
inline void add_logging_options(CLI::App& app, LoggingOptions& options) {
  app.add_option("--log-level", options.level, "trace, debug, info, warn, error, critical, off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
      ->capture_default_str();
  app.add_option("--log-format", options.format, "text, or json: one JSON object per line")
      ->check(CLI::IsMember({"text", "json"}))
      ->capture_default_str();
}

}  // namespace rayfarm
