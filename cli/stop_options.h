#pragma once
// The stopping rules and the reference image, as `rayfarm render` and `rayfarm submit` both take
// them (docs/error.md).
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "common/schedule/stop_rules.h"

namespace rayfarm::cli {

struct StopArgs {
  std::optional<std::string> reference;
  double target_error = 0.0;
  double time_limit = 0.0;
  bool no_adaptive = false;
  uint32_t min_passes = 0;

  StopRules rules() const {
    StopRules r;
    r.target_error = target_error;
    r.time_limit_s = time_limit;
    r.adaptive = !no_adaptive;
    r.min_passes = min_passes;
    return r;
  }
};

/// --clamp: off by default; when on, the image is biased (docs/error.md) and says so in its header.
inline void add_clamp_option(CLI::App* cmd, float& clamp) {
  cmd->add_option("--clamp", clamp,
                  "Scale down any sample whose largest component exceeds this: fewer fireflies, "
                  "but biased (recorded in the EXR as rayfarm:clamp; 0 = off, the default)")
      ->check(CLI::NonNegativeNumber);
}

/// --reference (described by `reference_help`), --target-error, --time-limit, --no-adaptive,
/// --min-passes.
inline void add_stop_options(CLI::App* cmd, StopArgs& args, const std::string& reference_help) {
  cmd->add_option("--reference", args.reference, reference_help);
  cmd->add_option("--target-error", args.target_error,
                  "Stop when the estimated relative MSE is below this (0 = no target)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--time-limit", args.time_limit, "Stop after this many seconds (0 = none)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-adaptive", args.no_adaptive,
                "With --target-error: whole passes over the image instead of stopping tile by tile");
  cmd->add_option("--min-passes", args.min_passes,
                  "Passes every tile gets before it may stop (0 = enough for 256 spp, at least 2)");
}

}  // namespace rayfarm::cli
