#include "master/scheduler.h"

#include <algorithm>

#include "common/util/check.h"

namespace rayfarm::master {
namespace {

/// Unit durations kept per job for its median.
constexpr size_t kDurationWindow = 64;

}  // namespace

void Scheduler::add_job(const std::string& job, const std::string& group, int64_t rank) {
  RAYFARM_CHECK(jobs_.count(job) == 0, "job added twice to the scheduler");
  Job j;
  j.group = group;
  j.rank = rank;
  jobs_.emplace(job, std::move(j));
  order_.push_back(job);
}

void Scheduler::set_priority(const std::string& job, int priority) {
  auto it = jobs_.find(job);
  if (it != jobs_.end()) it->second.priority = priority;
}

void Scheduler::set_paused(const std::string& job, bool paused) {
  auto it = jobs_.find(job);
  if (it != jobs_.end()) it->second.paused = paused;
}

void Scheduler::release(const std::string& job, const std::vector<uint64_t>& units) {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return;
  it->second.ready.insert(units.begin(), units.end());
}

void Scheduler::release_all(const std::string& job, uint64_t unit_count) {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return;
  RAYFARM_CHECK(it->second.fresh_end == 0, "every unit of a job released twice");
  it->second.next_fresh = 0;
  it->second.fresh_end = unit_count;
}

std::optional<uint64_t> Scheduler::take_pending(Job& j) {
  if (!j.requeued.empty()) {
    const uint64_t unit = *j.requeued.begin();
    j.requeued.erase(j.requeued.begin());
    return unit;
  }
  const bool fresh = j.next_fresh < j.fresh_end;
  if (!j.ready.empty() && (!fresh || *j.ready.begin() < j.next_fresh)) {
    const uint64_t unit = *j.ready.begin();
    j.ready.erase(j.ready.begin());
    return unit;
  }
  if (fresh) return j.next_fresh++;
  return std::nullopt;
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

bool Scheduler::has_pending(const Job& j) {
  return !j.requeued.empty() || !j.ready.empty() || j.next_fresh < j.fresh_end;
}

bool Scheduler::served_before(const Standing& a, const Standing& b) {
  if (a.priority != b.priority) return a.priority > b.priority;
  if (a.leases != b.leases) return a.leases < b.leases;
  return a.served < b.served;
}

std::optional<UnitRef> Scheduler::lease(const WorkerId& worker, Clock::time_point now,
                                        const std::string& key) {
  const std::string& who = key.empty() ? worker : key;
  // A group (a sequence's frames) competes as one job: its leases and its latest service are its
  // jobs' together, and it offers its lowest-ranked job that this worker may take.
  std::map<std::string, Standing> groups;
  for (const auto& [name, j] : jobs_) {
    if (j.group.empty()) continue;
    Standing& g = groups[j.group];
    g.leases += j.leased.size();
    g.served = std::max(g.served, j.served);
  }
  std::map<std::string, const std::string*> offered;  // group -> its job on offer
  for (const auto& name : order_) {
    const Job& j = jobs_.at(name);
    if (j.group.empty() || j.paused || j.blocked.count(who) || !has_pending(j)) continue;
    const std::string*& pick = offered[j.group];
    if (pick == nullptr || j.rank < jobs_.at(*pick).rank) pick = &name;
  }
  // The first best in the order of addition: ties go to the older job.
  const std::string* best = nullptr;
  Standing best_standing;
  for (const auto& name : order_) {
    const Job& j = jobs_.at(name);
    if (j.paused || j.blocked.count(who) || !has_pending(j)) continue;
    Standing standing{j.priority, j.leased.size(), j.served};
    if (!j.group.empty()) {
      if (offered.at(j.group) != &name) continue;
      standing = groups.at(j.group);
      standing.priority = j.priority;
    }
    if (best == nullptr || served_before(standing, best_standing)) {
      best = &name;
      best_standing = standing;
    }
  }
  if (best == nullptr) return std::nullopt;
  Job& best_job = jobs_.at(*best);
  const std::optional<uint64_t> unit = take_pending(best_job);
  RAYFARM_CHECK(unit.has_value(), "a job with units pending gave none");
  best_job.leased[*unit] = {Job::Holder{worker, now}};
  best_job.served = ++lease_serial_;
  by_worker_[worker].insert(UnitRef{*best, *unit});
  return UnitRef{*best, *unit};
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
  // Jobs by priority, the older first among equals (stable).
  std::vector<const std::string*> names;
  for (const auto& name : order_) names.push_back(&name);
  std::stable_sort(names.begin(), names.end(), [this](const std::string* a, const std::string* b) {
    return jobs_.at(*a).priority > jobs_.at(*b).priority;
  });
  for (const std::string* name_ptr : names) {
    const std::string& name = *name_ptr;
    Job& j = jobs_.at(name);
    if (j.paused || j.blocked.count(who)) continue;
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
    if (j.paused) continue;
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
  bool held = false;
  if (auto l = j.leased.find(unit.unit); l != j.leased.end()) {
    held = true;
    for (const auto& h : l->second) {
      if (by && h.worker == *by) {
        j.durations.push_back(std::chrono::duration<double>(now - h.since).count());
        if (j.durations.size() > kDurationWindow) j.durations.pop_front();
      }
      drop_lease(h.worker, unit);
    }
    j.leased.erase(l);
  }
  held = j.requeued.erase(unit.unit) > 0 || held;
  held = j.ready.erase(unit.unit) > 0 || held;
  return held;
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

bool Scheduler::has_pending() const {
  for (const auto& [name, j] : jobs_) {
    if (!j.paused && has_pending(j)) return true;
  }
  return false;
}

Scheduler::Counts Scheduler::counts(const std::string& job) const {
  Counts c;
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return c;
  const Job& j = it->second;
  c.leased = j.leased.size();
  std::set<WorkerId> workers;
  for (const auto& [unit, holders] : j.leased) {
    for (const auto& h : holders) workers.insert(h.worker);
  }
  c.workers = static_cast<uint32_t>(workers.size());
  return c;
}

std::vector<UnitRef> Scheduler::leased_units(const WorkerId& worker) const {
  auto w = by_worker_.find(worker);
  if (w == by_worker_.end()) return {};
  return {w->second.begin(), w->second.end()};
}

}  // namespace rayfarm::master
