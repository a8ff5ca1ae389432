#include "master/scheduler.h"

#include <algorithm>

#include "common/util/check.h"

namespace rayfarm::master {

void Scheduler::add_job(const std::string& job, uint64_t unit_count) {
  RAYFARM_CHECK(jobs_.count(job) == 0, "job added twice to the scheduler");
  Job j;
  j.total = unit_count;
  j.done.assign(unit_count, false);
  jobs_.emplace(job, std::move(j));
  order_.push_back(job);
}

void Scheduler::remove_job(const std::string& job) {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return;
  for (const auto& [unit, worker] : it->second.leased) {
    auto w = by_worker_.find(worker);
    if (w == by_worker_.end()) continue;
    w->second.erase(UnitRef{job, unit});
    if (w->second.empty()) by_worker_.erase(w);
  }
  jobs_.erase(it);
  order_.erase(std::remove(order_.begin(), order_.end(), job), order_.end());
}

std::optional<UnitRef> Scheduler::lease(const WorkerId& worker) {
  for (const auto& name : order_) {
    Job& j = jobs_.at(name);
    std::optional<uint64_t> unit;
    if (!j.requeued.empty()) {
      unit = *j.requeued.begin();
      j.requeued.erase(j.requeued.begin());
    } else {
      while (j.next_fresh < j.total && j.done[j.next_fresh]) ++j.next_fresh;
      if (j.next_fresh < j.total) unit = j.next_fresh++;
    }
    if (!unit) continue;
    j.leased.emplace(*unit, worker);
    by_worker_[worker].insert(UnitRef{name, *unit});
    return UnitRef{name, *unit};
  }
  return std::nullopt;
}

void Scheduler::drop_lease(const WorkerId& worker, const UnitRef& unit) {
  auto w = by_worker_.find(worker);
  if (w == by_worker_.end()) return;
  w->second.erase(unit);
  if (w->second.empty()) by_worker_.erase(w);
}

bool Scheduler::complete(const UnitRef& unit) {
  auto it = jobs_.find(unit.job);
  if (it == jobs_.end()) return false;
  Job& j = it->second;
  if (unit.unit >= j.total || j.done[unit.unit]) return false;
  if (auto l = j.leased.find(unit.unit); l != j.leased.end()) {
    drop_lease(l->second, unit);
    j.leased.erase(l);
  }
  j.requeued.erase(unit.unit);
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
  drop_lease(l->second, unit);
  j.leased.erase(l);
  j.requeued.insert(unit.unit);
  return true;
}

std::vector<UnitRef> Scheduler::release_worker(const WorkerId& worker) {
  auto w = by_worker_.find(worker);
  if (w == by_worker_.end()) return {};
  std::vector<UnitRef> units(w->second.begin(), w->second.end());
  by_worker_.erase(w);
  for (const auto& u : units) {
    Job& j = jobs_.at(u.job);
    j.leased.erase(u.unit);
    j.requeued.insert(u.unit);
  }
  return units;
}

std::optional<WorkerId> Scheduler::holder(const UnitRef& unit) const {
  auto it = jobs_.find(unit.job);
  if (it == jobs_.end()) return std::nullopt;
  auto l = it->second.leased.find(unit.unit);
  if (l == it->second.leased.end()) return std::nullopt;
  return l->second;
}

bool Scheduler::is_done(const UnitRef& unit) const {
  auto it = jobs_.find(unit.job);
  return it != jobs_.end() && unit.unit < it->second.total && it->second.done[unit.unit];
}

bool Scheduler::has_pending() const {
  for (const auto& [name, j] : jobs_) {
    if (j.done_count + j.leased.size() < j.total) return true;
  }
  return false;
}

Scheduler::Counts Scheduler::counts(const std::string& job) const {
  Counts c;
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return c;
  const Job& j = it->second;
  c.total = j.total;
  c.done = j.done_count;
  c.leased = j.leased.size();
  c.pending = j.total - j.done_count - c.leased;
  std::set<WorkerId> workers;
  for (const auto& [unit, worker] : j.leased) workers.insert(worker);
  c.workers = static_cast<uint32_t>(workers.size());
  return c;
}

size_t Scheduler::leases_of(const WorkerId& worker) const {
  auto w = by_worker_.find(worker);
  return w == by_worker_.end() ? 0 : w->second.size();
}

}  // namespace rayfarm::master
