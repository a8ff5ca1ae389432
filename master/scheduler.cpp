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
  j.added = ++added_;
  if (group.empty()) {
    order_.emplace(j.added, Entry{job, false});
  } else {
    auto [g, fresh] = groups_.try_emplace(group);
    if (fresh) {
      g->second.added = j.added;
      order_.emplace(j.added, Entry{group, true});
    }
    g->second.members.emplace(rank, job);
  }
  jobs_.emplace(job, std::move(j));
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

void Scheduler::set_group(const std::string& group, int priority, bool paused) {
  auto it = groups_.find(group);
  if (it == groups_.end()) return;
  it->second.priority = priority;
  it->second.paused = paused;
}

Scheduler::Group* Scheduler::group_of(const Job& j) {
  if (j.group.empty()) return nullptr;
  auto it = groups_.find(j.group);
  return it == groups_.end() ? nullptr : &it->second;
}

const Scheduler::Group* Scheduler::group_of(const Job& j) const {
  if (j.group.empty()) return nullptr;
  auto it = groups_.find(j.group);
  return it == groups_.end() ? nullptr : &it->second;
}

bool Scheduler::held(const Job& j) const {
  if (j.paused) return true;
  const Group* g = group_of(j);
  return g != nullptr && g->paused;
}

int Scheduler::priority_of(const Job& j) const {
  const Group* g = group_of(j);
  return g != nullptr ? g->priority : j.priority;
}

void Scheduler::open_lease(Job& j, uint64_t serial, uint32_t units) {
  j.open_leases[serial] = units;
  if (Group* g = group_of(j)) ++g->leases;
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
  Job& j = it->second;
  for (const auto& [unit, holders] : j.leased) {
    for (const auto& h : holders) drop_lease(h.worker, UnitRef{job, unit});
  }
  if (Group* g = group_of(j)) {
    g->leases -= std::min(g->leases, j.open_leases.size());
    g->members.erase({j.rank, job});
    if (g->members.empty()) {
      order_.erase(g->added);
      groups_.erase(j.group);
    }
  } else {
    order_.erase(j.added);
  }
  jobs_.erase(it);
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

const std::string* Scheduler::offer(const Group& group, const std::string& who) const {
  // In rank order, stopping at the first job that can be served: the jobs passed over are those
  // whose units are all out, those paused alone and those `who` is blocked from.
  for (const auto& [rank, name] : group.members) {
    const Job& j = jobs_.at(name);
    if (!j.paused && !j.blocked.count(who) && has_pending(j)) return &name;
  }
  return nullptr;
}

std::optional<Lease> Scheduler::lease_run(const WorkerId& worker, const RunPolicy& runs,
                                          Clock::time_point now, const std::string& key) {
  const std::string& who = key.empty() ? worker : key;
  // A group (a sequence's frames) competes as one job: its leases and its latest service are its
  // jobs' together, and it offers its lowest-ranked job that this worker may take. The first
  // best in the order of addition wins: ties go to the older job.
  const std::string* best = nullptr;
  Standing best_standing;
  for (const auto& [added, entry] : order_) {
    const std::string* name = nullptr;
    Standing standing;
    if (entry.group) {
      const Group& g = groups_.at(entry.name);
      if (g.paused) continue;
      name = offer(g, who);
      if (name == nullptr) continue;
      standing = Standing{g.priority, g.leases, g.served};
    } else {
      const Job& j = jobs_.at(entry.name);
      if (j.paused || j.blocked.count(who) || !has_pending(j)) continue;
      name = &entry.name;
      standing = Standing{j.priority, j.open_leases.size(), j.served};
    }
    if (best == nullptr || served_before(standing, best_standing)) {
      best = name;
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
  open_lease(best_job, serial, count);
  best_job.served = serial;
  if (Group* g = group_of(best_job)) g->served = serial;
  return out;
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
  if (open != j.open_leases.end() && --open->second == 0) {
    j.open_leases.erase(open);
    if (Group* g = group_of(j); g != nullptr && g->leases > 0) --g->leases;
  }
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
  // A held group is passed over whole; a group's jobs only until one has a unit pending.
  for (const auto& [added, entry] : order_) {
    if (entry.group) {
      const Group& g = groups_.at(entry.name);
      if (g.paused) continue;
      for (const auto& [rank, name] : g.members) {
        const Job& j = jobs_.at(name);
        if (!j.paused && has_pending(j)) return true;
      }
    } else {
      const Job& j = jobs_.at(entry.name);
      if (!j.paused && has_pending(j)) return true;
    }
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
  c.pending =
      j.ready.size() + j.requeued.size() + (j.fresh_end - j.next_fresh) - j.taken_ahead.size();
  return c;
}

bool Scheduler::is_leased(const UnitRef& unit) const {
  auto it = jobs_.find(unit.job);
  return it != jobs_.end() && it->second.leased.count(unit.unit) != 0;
}

std::vector<Scheduler::Holding> Scheduler::holdings(const std::string& job, size_t max) const {
  std::vector<Holding> out;
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return out;
  for (const auto& [unit, holders] : it->second.leased) {
    for (const auto& h : holders) {
      if (out.size() >= max) return out;
      out.push_back(Holding{unit, h.worker, h.since, h.lease});
    }
  }
  return out;
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
