#pragma once
// Leases units of work to workers that ask for them. Knows nothing of sockets or images: a job is
// a name and a number of units; a worker is an opaque id. Jobs are served in the order they were
// added; within a job the lowest-numbered pending unit goes first (pass-major, unit_grid.h). A
// worker's leases go back to the queue when it is lost, ahead of units never handed out.
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace rayfarm::master {

using WorkerId = std::string;

/// One unit of one job.
struct UnitRef {
  std::string job;
  uint64_t unit = 0;
  bool operator==(const UnitRef&) const = default;
  auto operator<=>(const UnitRef&) const = default;
};

class Scheduler {
 public:
  struct Counts {
    uint64_t total = 0, pending = 0, leased = 0, done = 0;
    uint32_t workers = 0;  ///< distinct workers holding leases of the job
  };

  /// Adds a job of `unit_count` units, all pending. A job id already present is a CHECK.
  void add_job(const std::string& job, uint64_t unit_count);
  /// Forgets a job (finished or cancelled) and its leases.
  void remove_job(const std::string& job);
  bool has_job(const std::string& job) const { return jobs_.count(job) != 0; }

  /// Leases the next pending unit to `worker`; nullopt when nothing is pending.
  std::optional<UnitRef> lease(const WorkerId& worker);
  /// Marks a unit done, whoever held it and even when it was back in the queue. Returns false
  /// when the job is unknown, the unit out of range, or the unit already done.
  bool complete(const UnitRef& unit);
  /// Puts a leased unit back in the queue (its worker failed it). False when it was not leased.
  bool requeue(const UnitRef& unit);
  /// Takes back every lease of `worker` (lost or gone) and returns those units, now pending.
  std::vector<UnitRef> release_worker(const WorkerId& worker);

  /// The worker holding `unit`, when it is leased.
  std::optional<WorkerId> holder(const UnitRef& unit) const;
  bool is_done(const UnitRef& unit) const;
  bool has_pending() const;
  Counts counts(const std::string& job) const;
  /// Units leased to `worker`.
  size_t leases_of(const WorkerId& worker) const;

 private:
  struct Job {
    uint64_t total = 0;
    uint64_t done_count = 0;
    uint64_t next_fresh = 0;      // units below it were handed out at least once
    std::set<uint64_t> requeued;  // units handed out, taken back, not done
    std::map<uint64_t, WorkerId> leased;
    std::vector<bool> done;
  };
  std::map<std::string, Job> jobs_;
  std::vector<std::string> order_;                   // jobs in the order they were added
  std::map<WorkerId, std::set<UnitRef>> by_worker_;  // leases per worker

  void drop_lease(const WorkerId& worker, const UnitRef& unit);
};

}  // namespace rayfarm::master
