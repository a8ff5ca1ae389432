#pragma once
// When a render stops, and why it stopped: the rules a job or `rayfarm render` is given besides
// its spp (docs/error.md), and the reason it ended.
#include <cstdint>

namespace rayfarm {

/// When a render stops besides its spp: the first rule reached ends it.
struct StopRules {
  double target_error = 0.0;  ///< estimated relative MSE; 0 = none
  double time_limit_s = 0.0;  ///< seconds of rendering; 0 = none
  bool adaptive = true;       ///< with a target: stop tile by tile rather than whole passes
  uint32_t min_passes = 0;    ///< passes before a tile may stop; 0 = default_min_passes()
};

/// Throws std::invalid_argument naming the rule and its range when `rules` cannot be followed:
/// a target error outside [0, 1e6) or a time limit outside [0, 1e9] s (or not a number).
void check_stop_rules(const StopRules& rules);

/// Passes a tile gets before its variance estimate is trusted: at least 2, and at least 256
/// samples per pixel. Fewer let the rare paths of caustics go unseen when the error budgets are
/// set (bench/adaptive.sh: with 64 samples, adaptive passes spent more than whole passes).
uint32_t default_min_passes(uint32_t pass_spp);

enum class StopReason { kRunning, kSpp, kTargetError, kTimeLimit, kCancelled, kFailed };
/// "running", "spp", "target error", "time limit", "cancelled", "failed".
const char* stop_reason_name(StopReason reason);

}  // namespace rayfarm
