#pragma once
// A running job's ETA, as status shows it. The estimated relative MSE falls as 1/t, so every error
// row (time t, estimate e) predicts the same finish time t * e / target; the rows' predictions are
// averaged over the last few rounds, so that the ETA counts down steadily instead of swinging with
// each round's estimate (and does not jump back to the time for every sample when one round's
// estimate dips below the target before the last tiles are done).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "common/report/error_log.h"
#include "common/schedule/stop_rules.h"

namespace rayfarm::master {

/// Rounds of error rows whose predictions are averaged.
inline constexpr size_t kEtaRows = 4;

/// Seconds left at `seconds` after the start: to the last sample at `rate` samples/s (when
/// known), or to the target error (predicted from `rows`) or the time limit when one comes first.
/// Negative when nothing is known yet.
inline double estimate_eta(const StopRules& stop, double remaining_samples, double rate,
                           double seconds, const std::vector<ErrorRow>& rows) {
  double eta = rate > 0 ? remaining_samples / rate : -1.0;
  if (stop.target_error > 0) {
    double sum = 0.0;
    size_t n = 0;
    for (size_t i = rows.size(); i > 0 && n < kEtaRows; --i) {
      const ErrorRow& row = rows[i - 1];
      if (!(row.time_s > 0) || !std::isfinite(row.est_rel_mse) || !(row.est_rel_mse > 0)) continue;
      sum += row.time_s * row.est_rel_mse / stop.target_error;
      ++n;
    }
    if (n > 0) {
      const double to_target = std::max(0.0, sum / static_cast<double>(n) - seconds);
      eta = eta < 0 ? to_target : std::min(eta, to_target);
    }
  }
  if (stop.time_limit_s > 0) {
    const double to_limit = std::max(0.0, stop.time_limit_s - seconds);
    eta = eta < 0 ? to_limit : std::min(eta, to_limit);
  }
  return eta;
}

}  // namespace rayfarm::master
