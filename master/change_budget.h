#pragma once
// How many state-changing requests (pause, resume, priority, cancel, retry, rm) one client key
// may make: a burst, refilled at a steady rate; past it, the request is refused with a message
// that says so. Each change costs the reactor a record on disk and a log line at least, so a key
// that toggles a job as fast as it can would otherwise take the reactor from the workers
// (docs/reliability.md, "Sequences and state changes").
#include <algorithm>
#include <chrono>
#include <map>
#include <string>

#include <fmt/format.h>

namespace rayfarm::master {

class ChangeBudget {
 public:
  using Clock = std::chrono::steady_clock;
  /// Changes a second, in the long run, per key.
  static constexpr double kPerSecond = 10;
  /// Changes a key may make at once, after a quiet spell.
  static constexpr double kBurst = 20;
  /// Keys followed at most: past it, the keys whose budget is full again are forgotten (they
  /// would start with a full budget anyway).
  static constexpr size_t kKeys = 4096;

  /// Whether `key` may make one more change at `now` (and takes it).
  bool take(const std::string& key, Clock::time_point now = Clock::now()) {
    if (buckets_.size() >= kKeys) forget_full(now);
    auto [it, fresh] = buckets_.try_emplace(key, Bucket{kBurst, now});
    Bucket& b = it->second;
    b.tokens = std::min(kBurst, b.tokens + kPerSecond * seconds(now - b.refilled));
    b.refilled = std::max(b.refilled, now);
    if (b.tokens < 1) return false;
    b.tokens -= 1;
    return true;
  }

  /// What a refused request is told.
  static std::string refusal() {
    return fmt::format(
        "too many changes from this key: at most {:g} a second (bursts of {:g}); try again in a "
        "moment",
        kPerSecond, kBurst);
  }

 private:
  struct Bucket {
    double tokens = kBurst;
    Clock::time_point refilled;
  };
  std::map<std::string, Bucket> buckets_;

  static double seconds(Clock::duration d) {
    return std::max(0.0, std::chrono::duration<double>(d).count());
  }
  void forget_full(Clock::time_point now) {
    std::erase_if(buckets_, [&](const auto& kv) {
      return kv.second.tokens + kPerSecond * seconds(now - kv.second.refilled) >= kBurst;
    });
    if (buckets_.size() >= kKeys) buckets_.clear();  // every key busy: start them all afresh
  }
};

}  // namespace rayfarm::master
