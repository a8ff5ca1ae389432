#pragma once
// The normal quantile that statistical tests compare their z-scores with: computed from the test
// level, never a constant taken from a table.
#include <cmath>

namespace rayfarm::testing {

/// z such that P(|Z| > z) = alpha for a standard normal Z: inverts erfc(z / sqrt 2) = alpha by
/// bisection.
inline double two_sided_z(double alpha) {
  double lo = 0.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (std::erfc(mid / std::sqrt(2.0)) > alpha ? lo : hi) = mid;
  }
  return hi;
}

}  // namespace rayfarm::testing
