#include "master/scheduler.h"

#include <algorithm>

#include "common/util/check.h"

namespace rayfarm::master {
namespace {

/// Unit durations kept per job for its median.
constexpr size_t kDurationWindow = 64;

}  // namespace

void Scheduler::add_job(const std::string& job, uint64_t unit_count, bool gated) {
  RAYFARM_CHECK(jobs_.count(job) == 0, "job added twice to the scheduler");
  Job j;
  j.total = unit_count;
  j.gated = gated;
  j.released = gated ? 0 : unit_count;
  if (gated) j.was_released.assign(unit_count, false);
  j.done.assign(unit_count, false);
  jobs_.emplace(job, std::move(j));
  order_.push_back(job);
}

void Scheduler::release(const std::string& job, const std::vector<uint64_t>& units) {
  auto it = jobs_.find(job);
  if (it == jobs_.end() || !it->second.gated) return;
  Job& j = it->second;
  for (uint64_t u : units) {
    if (u >= j.total || j.was_released[u]) continue;
    j.was_released[u] = true;
    ++j.released;
    if (!j.done[u]) j.ready.insert(u);
  }
}

void Scheduler::remove_job(const std::string& job) {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return;
  for (const auto& [unit, holders] : it->second.leased) {
    for (const auto& h : holders) drop_lease(h.worker, UnitRef{job, unit});
  }
  jobs_.erase(it);
  order_.erase(std::remove(order_.begin(), order_.end(), job), order_.end());
}

std::optional<UnitRef> Scheduler::lease(const WorkerId& worker, Clock::time_point now,
                                        const std::string& key) {
  const std::string& who = key.empty() ? worker : key;
  for (const auto& name : order_) {
    Job& j = jobs_.at(name);
    if (j.blocked.count(who)) continue;
    std::optional<uint64_t> unit;
    if (!j.requeued.empty()) {
      unit = *j.requeued.begin();
      j.requeued.erase(j.requeued.begin());
    } else if (j.gated) {
      if (!j.ready.empty()) {
        unit = *j.ready.begin();
        j.ready.erase(j.ready.begin());
      }
    } else {
      while (j.next_fresh < j.total && j.done[j.next_fresh]) ++j.next_fresh;
      if (j.next_fresh < j.total) unit = j.next_fresh++;
    }
    if (!unit) continue;
    j.leased[*unit] = {Job::Holder{worker, now}};
    by_worker_[worker].insert(UnitRef{name, *unit});
    return UnitRef{name, *unit};
  }
  return std::nullopt;
}

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
  for (const auto& name : order_) {
    Job& j = jobs_.at(name);
    if (j.blocked.count(who)) continue;
    const auto threshold = straggler_threshold(j, policy);
    if (!threshold) continue;
    // The slowest single lease past the threshold that `worker` does not hold.
    std::optional<uint64_t> slowest;
    double slowest_seconds = 0.0;
    for (const auto& [unit, holders] : j.leased) {
      if (holders.size() != 1 || holders.front().worker == worker) continue;
      const double seconds = std::chrono::duration<double>(now - holders.front().since).count();
      if (seconds > *threshold && seconds > slowest_seconds) {
        slowest = unit;
        slowest_seconds = seconds;
      }
    }
    if (!slowest) continue;
    auto& holders = j.leased.at(*slowest);
    StragglerLease out{UnitRef{name, *slowest}, holders.front().worker, slowest_seconds,
                       median(j.durations)};
    holders.push_back(Job::Holder{worker, now});
    by_worker_[worker].insert(out.unit);
    return out;
  }
  return std::nullopt;
}

bool Scheduler::has_straggler(const StragglerPolicy& policy, Clock::time_point now) const {
  for (const auto& [name, j] : jobs_) {
    const auto threshold = straggler_threshold(j, policy);
    if (!threshold) continue;
    for (const auto& [unit, holders] : j.leased) {
      if (holders.size() == 1 &&
          std::chrono::duration<double>(now - holders.front().since).count() > *threshold) {
        return true;
      }
    }
  }
  return false;
}

void Scheduler::drop_lease(const WorkerId& worker, const UnitRef& unit) {
  auto w = by_worker_.find(worker);
  if (w == by_worker_.end()) return;
  w->second.erase(unit);
  if (w->second.empty()) by_worker_.erase(w);
}

bool Scheduler::complete(const UnitRef& unit, const std::optional<WorkerId>& by,
                         Clock::time_point now) {
  auto it = jobs_.find(unit.job);
  if (it == jobs_.end()) return false;
  Job& j = it->second;
  if (unit.unit >= j.total || j.done[unit.unit]) return false;
  if (auto l = j.leased.find(unit.unit); l != j.leased.end()) {
    for (const auto& h : l->second) {
      if (by && h.worker == *by) {
        j.durations.push_back(std::chrono::duration<double>(now - h.since).count());
        if (j.durations.size() > kDurationWindow) j.durations.pop_front();
      }
      drop_lease(h.worker, unit);
    }
    j.leased.erase(l);
  }
  j.requeued.erase(unit.unit);
  j.ready.erase(unit.unit);
  j.done[unit.unit] = true;
  ++j.done_count;
  return true;
}

bool Scheduler::requeue(const UnitRef& unit) {
  auto it = jobs_.find(unit.job);
  if (it == jobs_.end()) return false;
  Job& j = it->second;
  auto l = j.leased.find(unit.unit);
  if (l == j.leased.end()) return false;
  for (const auto& h : l->second) drop_lease(h.worker, unit);
  j.leased.erase(l);
  j.requeued.insert(unit.unit);
  return true;
}

bool Scheduler::requeue(const UnitRef& unit, const WorkerId& worker) {
  auto it = jobs_.find(unit.job);
  if (it == jobs_.end()) return false;
  Job& j = it->second;
  auto l = j.leased.find(unit.unit);
  if (l == j.leased.end()) return false;
  auto& holders = l->second;
  auto h = std::find_if(holders.begin(), holders.end(),
                        [&](const Job::Holder& x) { return x.worker == worker; });
  if (h == holders.end()) return false;
  holders.erase(h);
  drop_lease(worker, unit);
  if (holders.empty()) {
    j.leased.erase(l);
    j.requeued.insert(unit.unit);
  }
  return true;
}

std::vector<UnitRef> Scheduler::release_worker(const WorkerId& worker) {
  auto w = by_worker_.find(worker);
  if (w == by_worker_.end()) return {};
  const std::vector<UnitRef> units(w->second.begin(), w->second.end());
  by_worker_.erase(w);
  std::vector<UnitRef> requeued;
  for (const auto& u : units) {
    Job& j = jobs_.at(u.job);
    auto l = j.leased.find(u.unit);
    if (l == j.leased.end()) continue;
    auto& holders = l->second;
    holders.erase(std::remove_if(holders.begin(), holders.end(),
                                 [&](const Job::Holder& x) { return x.worker == worker; }),
                  holders.end());
    if (!holders.empty()) continue;  // the other holder of a straggler carries on
    j.leased.erase(l);
    j.requeued.insert(u.unit);
    requeued.push_back(u);
  }
  return requeued;
}

void Scheduler::block(const std::string& job, const std::string& who) {
  auto it = jobs_.find(job);
  if (it != jobs_.end()) it->second.blocked.insert(who);
}

bool Scheduler::is_blocked(const std::string& job, const std::string& who) const {
  auto it = jobs_.find(job);
  return it != jobs_.end() && it->second.blocked.count(who) != 0;
}

bool Scheduler::holds(const UnitRef& unit, const WorkerId& worker) const {
  auto w = by_worker_.find(worker);
  return w != by_worker_.end() && w->second.count(unit) != 0;
}

double Scheduler::median_seconds(const std::string& job) const {
  auto it = jobs_.find(job);
  return it == jobs_.end() ? 0.0 : median(it->second.durations);
}

std::optional<WorkerId> Scheduler::holder(const UnitRef& unit) const {
  auto it = jobs_.find(unit.job);
  if (it == jobs_.end()) return std::nullopt;
  auto l = it->second.leased.find(unit.unit);
  if (l == it->second.leased.end() || l->second.empty()) return std::nullopt;
  return l->second.front().worker;
}

std::vector<WorkerId> Scheduler::holders(const UnitRef& unit) const {
  std::vector<WorkerId> out;
  auto it = jobs_.find(unit.job);
  if (it == jobs_.end()) return out;
  auto l = it->second.leased.find(unit.unit);
  if (l == it->second.leased.end()) return out;
  for (const auto& h : l->second) out.push_back(h.worker);
  return out;
}

bool Scheduler::is_done(const UnitRef& unit) const {
  auto it = jobs_.find(unit.job);
  return it != jobs_.end() && unit.unit < it->second.total && it->second.done[unit.unit];
}

bool Scheduler::has_pending() const {
  for (const auto& [name, j] : jobs_) {
    if (j.done_count + j.leased.size() < j.released) return true;
  }
  return false;
}

Scheduler::Counts Scheduler::counts(const std::string& job) const {
  Counts c;
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return c;
  const Job& j = it->second;
  c.total = j.released;
  c.done = j.done_count;
  c.leased = j.leased.size();
  c.pending = j.released > j.done_count + c.leased ? j.released - j.done_count - c.leased : 0;
  std::set<WorkerId> workers;
  for (const auto& [unit, holders] : j.leased) {
    for (const auto& h : holders) workers.insert(h.worker);
  }
  c.workers = static_cast<uint32_t>(workers.size());
  return c;
}

size_t Scheduler::leases_of(const WorkerId& worker) const {
  auto w = by_worker_.find(worker);
  return w == by_worker_.end() ? 0 : w->second.size();
}

std::vector<UnitRef> Scheduler::leased_units(const WorkerId& worker) const {
  auto w = by_worker_.find(worker);
  if (w == by_worker_.end()) return {};
  return {w->second.begin(), w->second.end()};
}

}  // namespace rayfarm::master
