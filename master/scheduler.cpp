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

void Scheduler::set_run_stride(const std::string& job, uint64_t stride) {
  auto it = jobs_.find(job);
  if (it != jobs_.end()) it->second.stride = stride;
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
  if (fresh) return take_fresh(j);
  return std::nullopt;
}

uint64_t Scheduler::take_fresh(Job& j) {
  const uint64_t unit = j.next_fresh++;
  while (j.next_fresh < j.fresh_end && j.taken_ahead.erase(j.next_fresh) > 0) ++j.next_fresh;
  return unit;
}

bool Scheduler::take_if_pending(Job& j, uint64_t unit) {
  if (j.requeued.erase(unit) > 0 || j.ready.erase(unit) > 0) return true;
  if (unit < j.next_fresh || unit >= j.fresh_end || j.taken_ahead.count(unit) != 0) return false;
  if (unit == j.next_fresh) {
    take_fresh(j);
  } else {
    j.taken_ahead.insert(unit);
  }
  return true;
}

uint32_t Scheduler::run_length(const Job& j, const WorkerId& worker, const RunPolicy& runs) {
  if (j.stride == 0 || runs.target.count() <= 0 || runs.max_units <= 1) return 1;
  auto it = j.unit_seconds.find(worker);
  if (it == j.unit_seconds.end()) return 1;  // not measured yet on this job
  const double units = it->second > 0 ? runs.target.count() / it->second : runs.max_units;
  return static_cast<uint32_t>(std::clamp(units, 1.0, static_cast<double>(runs.max_units)));
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
  const auto run = lease_run(worker, RunPolicy{}, now, key);
  if (!run) return std::nullopt;
  return UnitRef{run->job, run->units.front()};
}

std::optional<Lease> Scheduler::lease_run(const WorkerId& worker, const RunPolicy& runs,
                                          Clock::time_point now, const std::string& key) {
  const std::string& who = key.empty() ? worker : key;
  // A group (a sequence's frames) competes as one job: its leases and its latest service are its
  // jobs' together, and it offers its lowest-ranked job that this worker may take.
  std::map<std::string, Standing> groups;
  for (const auto& [name, j] : jobs_) {
    if (j.group.empty()) continue;
    Standing& g = groups[j.group];
    g.leases += j.open_leases.size();
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
    Standing standing{j.priority, j.open_leases.size(), j.served};
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
  Lease out{*best, {*unit}};
  const uint32_t length = run_length(best_job, worker, runs);
  while (out.units.size() < length &&
         take_if_pending(best_job, out.units.back() + best_job.stride)) {
    out.units.push_back(out.units.back() + best_job.stride);
  }
  const uint64_t serial = ++lease_serial_;
  const auto count = static_cast<uint32_t>(out.units.size());
  for (const uint64_t u : out.units) {
    best_job.leased[u] = {Job::Holder{worker, now, serial, count}};
    by_worker_[worker].insert(UnitRef{*best, u});
  }
  best_job.open_leases[serial] = count;
  best_job.served = serial;
  return out;
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
    j.open_leases[serial] = count;
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
          std::chrono::duration<double>(now - holders.front().since).count() /
                  holders.front().units >
              *threshold) {
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

void Scheduler::unhold(Job& j, const Job::Holder& h, const UnitRef& unit) {
  drop_lease(h.worker, unit);
  auto open = j.open_leases.find(h.lease);
  if (open != j.open_leases.end() && --open->second == 0) j.open_leases.erase(open);
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
        const double per_unit = std::chrono::duration<double>(now - h.since).count() / h.units;
        j.durations.push_back(per_unit);
        if (j.durations.size() > kDurationWindow) j.durations.pop_front();
        j.unit_seconds[h.worker] = per_unit;
      }
      unhold(j, h, unit);
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
  for (const auto& h : l->second) unhold(j, h, unit);
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
  unhold(j, *h, unit);
  holders.erase(h);
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
  for (auto& [name, j] : jobs_) j.unit_seconds.erase(worker);
  std::vector<UnitRef> requeued;
  for (const auto& u : units) {
    Job& j = jobs_.at(u.job);
    auto l = j.leased.find(u.unit);
    if (l == j.leased.end()) continue;
    auto& holders = l->second;
    const auto gone = std::remove_if(holders.begin(), holders.end(),
                                     [&](const Job::Holder& x) { return x.worker == worker; });
    for (auto h = gone; h != holders.end(); ++h) unhold(j, *h, u);
    holders.erase(gone, holders.end());
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

std::vector<uint64_t> Scheduler::lease_of(const UnitRef& unit, const WorkerId& worker) const {
  auto it = jobs_.find(unit.job);
  if (it == jobs_.end()) return {};
  const Job& j = it->second;
  auto holder_in = [&](uint64_t u) -> const Job::Holder* {
    auto l = j.leased.find(u);
    if (l == j.leased.end()) return nullptr;
    for (const auto& h : l->second) {
      if (h.worker == worker) return &h;
    }
    return nullptr;
  };
  const Job::Holder* mine = holder_in(unit.unit);
  if (mine == nullptr) return {};
  const uint64_t serial = mine->lease;
  std::vector<uint64_t> out;
  auto w = by_worker_.find(worker);
  for (auto r = w->second.lower_bound(UnitRef{unit.job, 0});
       r != w->second.end() && r->job == unit.job; ++r) {
    const Job::Holder* h = holder_in(r->unit);
    if (h != nullptr && h->lease == serial) out.push_back(r->unit);
  }
  return out;
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

std::optional<double> Scheduler::unit_seconds(const std::string& job,
                                              const WorkerId& worker) const {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return std::nullopt;
  auto w = it->second.unit_seconds.find(worker);
  if (w == it->second.unit_seconds.end()) return std::nullopt;
  return w->second;
}

}  // namespace rayfarm::master
