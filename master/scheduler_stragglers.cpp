// The scheduler's stragglers: a lease running far longer than its job's median unit is leased a
// second time to an idle worker (docs/farm.md, "Leases"). Only the jobs holding leases are looked
// at, whatever the number of jobs queued.
#include <algorithm>

#include "master/scheduler.h"

namespace rayfarm::master {

double Scheduler::median(const std::deque<double>& values) {
  if (values.empty()) return 0.0;
  std::vector<double> v(values.begin(), values.end());
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

std::optional<double> Scheduler::straggler_threshold(const Job& j, const StragglerPolicy& policy) {
  if (policy.factor <= 0 || j.durations.size() < std::max<size_t>(policy.min_samples, 1)) {
    return std::nullopt;
  }
  return std::max(policy.factor * median(j.durations),
                  std::chrono::duration<double>(policy.floor).count());
}

std::optional<Scheduler::StragglerLease> Scheduler::lease_straggler(const WorkerId& worker,
                                                                    const StragglerPolicy& policy,
                                                                    Clock::time_point now,
                                                                    const std::string& key) {
  const std::string& who = key.empty() ? worker : key;
  // The jobs that hold leases (only they can have a straggler), by priority, the older first
  // among equals: as many as there are leases out, whatever the number of jobs.
  std::vector<const std::string*> names;
  for (const std::string* name : leased_jobs()) {
    const Job& j = jobs_.at(*name);
    if (!held(j) && !j.blocked.count(who)) names.push_back(name);
  }
  std::sort(names.begin(), names.end(), [this](const std::string* a, const std::string* b) {
    const Job& ja = jobs_.at(*a);
    const Job& jb = jobs_.at(*b);
    const int pa = priority_of(ja), pb = priority_of(jb);
    return pa != pb ? pa > pb : ja.added < jb.added;
  });
  for (const std::string* name_ptr : names) {
    const std::string& name = *name_ptr;
    Job& j = jobs_.at(name);
    const auto threshold = straggler_threshold(j, policy);
    if (!threshold) continue;
    // The slowest single lease, per unit, past the threshold that `worker` does not hold.
    const Job::Holder* slowest = nullptr;
    double slowest_per_unit = 0.0;
    for (const auto& [unit, holders] : j.leased) {
      if (holders.size() != 1 || holders.front().worker == worker) continue;
      const Job::Holder& h = holders.front();
      const double per_unit = std::chrono::duration<double>(now - h.since).count() / h.units;
      if (per_unit > *threshold && per_unit > slowest_per_unit) {
        slowest = &h;
        slowest_per_unit = per_unit;
      }
    }
    if (slowest == nullptr) continue;
    const Job::Holder first = *slowest;
    StragglerLease out;
    for (const auto& [unit, holders] : j.leased) {
      if (holders.size() == 1 && holders.front().lease == first.lease) out.units.push_back(unit);
    }
    out.unit = UnitRef{name, out.units.front()};
    out.first = first.worker;
    out.leased_seconds = std::chrono::duration<double>(now - first.since).count();
    out.median_seconds = median(j.durations);
    const uint64_t serial = ++lease_serial_;
    const auto count = static_cast<uint32_t>(out.units.size());
    for (const uint64_t unit : out.units) {
      j.leased.at(unit).push_back(Job::Holder{worker, now, serial, count});
      by_worker_[worker].insert(UnitRef{name, unit});
    }
    open_lease(j, serial, count);
    return out;
  }
  return std::nullopt;
}

std::vector<const std::string*> Scheduler::leased_jobs() const {
  std::set<const std::string*> out;
  for (const auto& [worker, units] : by_worker_) {
    for (const UnitRef& u : units) {
      auto it = jobs_.find(u.job);
      if (it != jobs_.end()) out.insert(&it->first);
    }
  }
  return {out.begin(), out.end()};
}

bool Scheduler::has_straggler(const StragglerPolicy& policy, Clock::time_point now) const {
  for (const std::string* name : leased_jobs()) {
    const Job& j = jobs_.at(*name);
    if (held(j)) continue;
    const auto threshold = straggler_threshold(j, policy);
    if (!threshold) continue;
    for (const auto& [unit, holders] : j.leased) {
      if (holders.size() == 1 &&
          std::chrono::duration<double>(now - holders.front().since).count() /
                  holders.front().units >
              *threshold) {
        return true;
      }
    }
  }
  return false;
}

}  // namespace rayfarm::master
