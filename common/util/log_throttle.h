#pragma once
// A log line that may repeat many times a second (a message dropped, garbage from a peer) is
// logged the first time, then at most once per interval, and that line tells how many were not
// logged since the previous one. Not thread-safe: one throttle per thread or per guarded state.
#include <chrono>
#include <cstdint>
#include <string>

namespace rayfarm {

class LogThrottle {
 public:
  using Clock = std::chrono::steady_clock;

  explicit LogThrottle(Clock::duration interval) : interval_(interval) {}

  /// Whether to log the occurrence at `now`, and how many before it were not logged.
  struct Verdict {
    bool log = false;
    uint64_t unlogged = 0;
  };

  /// Counts one occurrence. The first is logged; later ones are logged when `interval` has passed
  /// since the last line, with the count of those not logged in between.
  Verdict occur(Clock::time_point now = Clock::now()) {
    ++total_;
    if (logged_once_ && now - last_logged_ < interval_) {
      ++unlogged_;
      return {false, 0};
    }
    const Verdict verdict{true, unlogged_};
    logged_once_ = true;
    last_logged_ = now;
    unlogged_ = 0;
    return verdict;
  }

  /// Occurrences counted so far, logged or not.
  uint64_t total() const { return total_; }

  /// " (N more since the last line)" when `verdict` counts some not logged, else "": a suffix for
  /// the line logged.
  static std::string suffix(const Verdict& verdict) {
    if (verdict.unlogged == 0) return {};
    return " (" + std::to_string(verdict.unlogged) + " more since the last line)";
  }

 private:
  Clock::duration interval_;
  bool logged_once_ = false;
  Clock::time_point last_logged_{};
  uint64_t unlogged_ = 0;
  uint64_t total_ = 0;
};

}  // namespace rayfarm
