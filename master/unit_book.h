#pragma once
// What a running job's detail view shows of its units beyond the scheduler's leases: how often
// each unit not merged yet was handed out and why it last failed, the latest units merged (those
// that needed more than one lease kept apart, so that routine merges do not push them out), and
// what each worker did for the job. Every part is bounded: a job of a million units costs this a
// few hundred entries besides one counter per unit handed out and not merged yet.
#include <algorithm>
#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <unordered_map>

#include "master/job_log.h"

namespace rayfarm::master {

class UnitBook {
 public:
  /// A unit (or the first of a run) as it was merged.
  struct Done {
    uint64_t unit = 0;
    uint32_t units = 1;  ///< units the result covered (a run of one tile's passes)
    std::string worker;
    double render_seconds = 0;
    uint32_t leases = 1;
    std::string error;  ///< its latest failure before it merged
  };
  /// What one worker did for the job.
  struct Share {
    uint64_t units_done = 0;
    double render_seconds = 0;
    uint32_t failures = 0;
  };
  /// Not merged yet: times handed out and the latest failure.
  struct Open {
    uint32_t leases = 0;
    bool failed = false;
    std::string error;
  };

  static constexpr size_t kRecentKept = 32;
  static constexpr size_t kTroubledKept = 64;
  static constexpr size_t kSharesKept = 256;
  static constexpr size_t kErrorChars = 300;

  /// `unit` was handed out (again).
  void leased(uint64_t unit) {
    Open& o = open_[unit];
    if (++o.leases == 2) ++retried_;
  }
  /// `worker` failed `unit`, saying `why` (its own words, made printable by the caller).
  void failed(uint64_t unit, const std::string& worker, const std::string& why) {
    Open& o = open_[unit];
    if (!o.failed) ++failed_;
    o.failed = true;
    o.error = why.empty() ? "(no reason given)" : JobLog::clean(why.substr(0, kErrorChars));
    if (Share* s = share(worker)) ++s->failures;
  }
  /// `units` units from `first` on (a run: every `stride`-th) were merged from `worker`'s result.
  void merged(uint64_t first, uint32_t units, uint64_t stride, const std::string& worker,
              double render_seconds) {
    Done d{first, units, worker, render_seconds, 1, {}};
    for (uint32_t k = 0; k < units; ++k) {
      auto it = open_.find(first + k * stride);
      if (it == open_.end()) continue;
      d.leases = std::max(d.leases, it->second.leases);
      if (!it->second.error.empty()) d.error = it->second.error;
      open_.erase(it);
    }
    if (Share* s = share(worker)) {
      s->units_done += units;
      s->render_seconds += render_seconds;
    }
    auto& into = d.leases > 1 || !d.error.empty() ? troubled_ : recent_;
    into.push_back(std::move(d));
    if (into.size() > (&into == &troubled_ ? kTroubledKept : kRecentKept)) into.pop_front();
  }

  const std::unordered_map<uint64_t, Open>& open() const { return open_; }
  const std::deque<Done>& recent() const { return recent_; }
  const std::deque<Done>& troubled() const { return troubled_; }
  const std::map<std::string, Share>& shares() const { return shares_; }
  /// Units handed out more than once, and units that failed at least once, since the job began.
  uint64_t retried() const { return retried_; }
  uint64_t failed_units() const { return failed_; }

 private:
  std::unordered_map<uint64_t, Open> open_;
  std::deque<Done> recent_, troubled_;
  std::map<std::string, Share> shares_;
  uint64_t retried_ = 0, failed_ = 0;

  /// The worker's share; nullptr once kSharesKept workers have one (the rest go uncounted).
  Share* share(const std::string& worker) {
    auto it = shares_.find(worker);
    if (it != shares_.end()) return &it->second;
    if (shares_.size() >= kSharesKept) return nullptr;
    return &shares_[worker];
  }
};

}  // namespace rayfarm::master
