#include "common/schedule/stop_rules.h"

#include <algorithm>
#include <sstream>
#include <stdexcept>

namespace rayfarm {

void check_stop_rules(const StopRules& rules) {
  const auto fail = [](const char* what, double value) {
    std::ostringstream out;
    out << what << value;
    throw std::invalid_argument(out.str());
  };
  if (!(rules.target_error >= 0 && rules.target_error < 1e6))
    fail("target error must be in [0, 1e6), got ", rules.target_error);
  if (!(rules.time_limit_s >= 0 && rules.time_limit_s <= 1e9))
    fail("time limit must be in [0, 1e9] s, got ", rules.time_limit_s);
}

uint32_t default_min_passes(uint32_t pass_spp) {
  const uint32_t enough = pass_spp == 0 ? 256 : (256 + pass_spp - 1) / pass_spp;
  return std::max<uint32_t>(2, enough);
}

const char* stop_reason_name(StopReason reason) {
  switch (reason) {
    case StopReason::kRunning:
      return "running";
    case StopReason::kSpp:
      return "spp";
    case StopReason::kTargetError:
      return "target error";
    case StopReason::kTimeLimit:
      return "time limit";
    case StopReason::kCancelled:
      return "cancelled";
    case StopReason::kFailed:
      return "failed";
  }
  return "unknown";
}

}  // namespace rayfarm
