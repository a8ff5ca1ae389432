#pragma once
// How many log lines a peer may cause: a burst per key, refilled at one a second; past it, the
// caller logs at debug level. Keeps a flood of messages from one key from flooding the log while
// a few refusals or duplicates are all shown.
#include <algorithm>
#include <chrono>
#include <map>
#include <string>

namespace rayfarm::master {

class LogBudget {
 public:
  static constexpr double kBurst = 32;

  /// Whether `who` may cause one more line now (and takes it).
  bool take(const std::string& who) {
    if (buckets_.size() > 4096) buckets_.clear();
    Bucket& b = buckets_[who];
    const auto now = Clock::now();
    b.tokens = std::min(kBurst, b.tokens + std::chrono::duration<double>(now - b.refilled).count());
    b.refilled = now;
    if (b.tokens < 1) return false;
    b.tokens -= 1;
    return true;
  }

 private:
  using Clock = std::chrono::steady_clock;
  struct Bucket {
    double tokens = kBurst;
    Clock::time_point refilled = Clock::now();
  };
  std::map<std::string, Bucket> buckets_;
};

}  // namespace rayfarm::master
