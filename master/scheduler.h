#pragma once
// Leases units of work to workers that ask for them. Knows nothing of sockets or images: a job is
// a name and the units released to it; a worker is an opaque id. The scheduler owns leases and
// the queue of units waiting for one, nothing else: which units are released is the pass
// planner's (common/schedule/pass_planner.h), which are merged the merger's, and the job manager
// releases a unit here once, when it is released and not merged.
//
// Which job a free worker serves: among the jobs with a unit pending that are not paused (and
// that the worker is not blocked from), one of the highest priority; among those, the job that
// holds the fewest leases now, then the one served longest ago, then the oldest, so that jobs of
// equal priority share the workers evenly and a job submitted behind a long one gets the next
// worker that frees up. A job of higher priority takes every worker it can use first. The jobs of
// a group (the frames of a sequence) count as one job in that choice, and the group serves its
// lowest-ranked job with a unit pending first: frames finish in order. A group's priority and
// pause are the group's, set once for all its jobs (set_group): changing them costs the same
// whatever the group's size, and a lease looks at a group's jobs in rank order only until it
// finds one to serve. Within a
// job the lowest-numbered pending unit goes first (pass-major, common/schedule/unit_grid.h). A
// worker's leases go back to the queue when it is lost, ahead of units never handed out. Pausing a
// job stops new leases of it (second leases too); the leases it holds run to their end.
//
// Runs: a lease may cover a run of units, one tile's consecutive passes (units u, u + stride,
// u + 2 stride, ...: the unit grid's numbering), sized by RunPolicy so that the run takes about a
// target time on the worker that gets it, from how long that worker's latest lease of the job took
// per unit. A run takes only units that are pending, so it never reaches past what the pass planner
// released. The image does not depend on runs: a run's samples are the same samples, and the
// master merges their exact sums as the units they cover. Fair sharing counts leases, not units.
//
// Failures and slow workers: a worker can be blocked from a job (it keeps failing there) and is
// then given only other jobs' units. A unit leased for much longer than its job's median unit
// (StragglerPolicy) may be leased a second time to a worker that has nothing else to do; both
// leases then stand until either result completes the unit, which ends both.
#include <chrono>
#include <cstdint>
#include <deque>
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

/// How many units one lease covers (see "Runs" at the top of this file).
struct RunPolicy {
  /// The time a lease should take on the worker that gets it; 0: one unit per lease.
  std::chrono::duration<double> target{0};
  /// The most units one lease covers.
  uint32_t max_units = 32;
};

/// The units of one lease: one, or a run of one tile's consecutive passes, ascending.
struct Lease {
  std::string job;
  std::vector<uint64_t> units;
};

/// When a unit is slow enough to be leased a second time.
struct StragglerPolicy {
  /// Leased for longer than factor x the job's median unit duration; 0 = never.
  double factor = 4.0;
  /// ... and for longer than this.
  std::chrono::milliseconds floor{5000};
  /// The median is trusted once this many units of the job are done.
  size_t min_samples = 3;
};

class Scheduler {
 public:
  using Clock = std::chrono::steady_clock;

  /// A lease taken a second time because the first is slow: every unit of the first lease.
  struct StragglerLease {
    UnitRef unit;                 ///< the first unit of the lease
    std::vector<uint64_t> units;  ///< all of them (a run), ascending
    WorkerId first;               ///< who holds the first lease
    double leased_seconds = 0;    ///< how long the first lease has run
    double median_seconds = 0;    ///< the job's median unit duration
  };

  struct Counts {
    uint64_t leased = 0;   ///< units leased now
    uint32_t workers = 0;  ///< distinct workers holding leases of the job
    uint64_t pending = 0;  ///< units released and waiting for a lease
  };
  /// One worker's lease of one unit, as a job's detail view shows it.
  struct Holding {
    uint64_t unit = 0;
    WorkerId worker;
    Clock::time_point since;
    uint64_t lease = 0;  ///< the lease's serial: the units of a run share it
  };

  /// Adds a job with no unit pending yet, of priority 0, not paused. A job id already present is
  /// a CHECK. Jobs of one `group` (a sequence's frames) share the workers as one job, and within
  /// it the lowest `rank` (the frame number) that has a unit pending goes first.
  void add_job(const std::string& job, const std::string& group = {}, int64_t rank = 0);
  /// Units u, u + stride, u + 2 stride, ... of the job are one tile's consecutive passes, which a
  /// lease may cover together (lease_run); 0 (the default): every lease is one unit.
  void set_run_stride(const std::string& job, uint64_t stride);
  /// Higher priorities are served first (see the top of this file). Unknown jobs are ignored.
  void set_priority(const std::string& job, int priority);
  /// A paused job gets no new leases (nor second leases of its stragglers) until resumed.
  void set_paused(const std::string& job, bool paused);
  /// The priority of every job of `group` (their own set_priority is not used), and whether the
  /// whole group is held (a job of it is then paused whatever its own flag says). O(log groups);
  /// ignored while the group has no job. A group's jobs added later take it.
  void set_group(const std::string& group, int priority, bool paused);
  /// Makes `units` of the job pending. Each unit is released once (the caller's planner decides).
  void release(const std::string& job, const std::vector<uint64_t>& units);
  /// Makes units [0, unit_count) of the job pending: a job that needs every unit, held in O(1).
  void release_all(const std::string& job, uint64_t unit_count);
  /// Forgets a job (finished or cancelled) and its leases.
  void remove_job(const std::string& job);

  /// Leases the next pending unit of a job `worker` is not blocked from, with the pending units
  /// that follow it in its tile's passes as `runs` sizes the lease; nullopt when none. `key`
  /// names the identity blocks apply to (the worker's key, shared by every connection made with
  /// it); empty: the worker itself.
  std::optional<Lease> lease_run(const WorkerId& worker, const RunPolicy& runs,
                                 Clock::time_point now = Clock::now(), const std::string& key = {});
  /// lease_run() of one unit.
  std::optional<UnitRef> lease(const WorkerId& worker, Clock::time_point now = Clock::now(),
                               const std::string& key = {});
  /// Leases to `worker` a second copy of the slowest straggler lease (policy: its time per unit)
  /// that it does not hold, of a job it is not blocked from and that is not paused, of the
  /// highest priority that has one; nullopt when there is none.
  std::optional<StragglerLease> lease_straggler(const WorkerId& worker,
                                                const StragglerPolicy& policy,
                                                Clock::time_point now = Clock::now(),
                                                const std::string& key = {});
  /// Some leased unit is a straggler that no second worker holds yet.
  bool has_straggler(const StragglerPolicy& policy, Clock::time_point now = Clock::now()) const;
  /// The unit is merged, whoever held it and even when it was back in the queue: every lease of
  /// it ends and it leaves the queue for good. `by`, when it held a lease, gives the lease's time
  /// per unit to the job's median and to the sizing of its next runs of the job. Returns false when
  /// the unit was neither leased nor queued (an unknown job, or a unit completed before).
  bool complete(const UnitRef& unit, const std::optional<WorkerId>& by = std::nullopt,
                Clock::time_point now = Clock::now());
  /// Puts a leased unit back in the queue, dropping every lease of it. False when not leased.
  bool requeue(const UnitRef& unit);
  /// Ends `worker`'s lease of `unit` (it failed it); the unit goes back to the queue unless
  /// another worker still holds it. False when `worker` did not hold it.
  bool requeue(const UnitRef& unit, const WorkerId& worker);
  /// Takes back every lease of `worker` (lost or gone) and returns the units that are pending
  /// again (a unit another worker also holds stays leased to that worker).
  std::vector<UnitRef> release_worker(const WorkerId& worker);

  /// `who` (a worker, or the key of lease()) gets no more units of `job` (it keeps failing
  /// there); current leases stand.
  void block(const std::string& job, const std::string& who);
  bool is_blocked(const std::string& job, const std::string& who) const;
  /// The units of `worker`'s lease that includes `unit` (one, or every unit of a run), ascending;
  /// empty when `worker` does not hold `unit`.
  std::vector<uint64_t> lease_of(const UnitRef& unit, const WorkerId& worker) const;
  /// Whether some worker holds a lease of `unit` now.
  bool is_leased(const UnitRef& unit) const;
  /// Whether `worker` holds a lease of `unit` now.
  bool holds(const UnitRef& unit, const WorkerId& worker) const;
  /// Some unit of some job that is not paused waits for a lease.
  bool has_pending() const;
  Counts counts(const std::string& job) const;
  /// The job's leases now, unit by unit in unit order (a straggler's two holders each); at most
  /// `max`.
  std::vector<Holding> holdings(const std::string& job, size_t max) const;
  /// The units leased to `worker`, in order.
  std::vector<UnitRef> leased_units(const WorkerId& worker) const;
  /// Seconds per unit of `worker`'s latest lease of `job` that completed; nullopt when none has.
  std::optional<double> unit_seconds(const std::string& job, const WorkerId& worker) const;

 private:
  struct Job {
    // Released, never handed out: the units of `ready` and those of [next_fresh, fresh_end).
    std::set<uint64_t> ready;
    uint64_t next_fresh = 0, fresh_end = 0;
    std::set<uint64_t>
        taken_ahead;              // of [next_fresh, fresh_end), leased in a run; never next_fresh
    std::set<uint64_t> requeued;  // units handed out, taken back, not merged
    struct Holder {
      WorkerId worker;
      Clock::time_point since;
      uint64_t lease = 0;  // the lease's serial, shared by the units of a run
      uint32_t units = 1;  // units the lease covered
    };
    std::map<uint64_t, std::vector<Holder>> leased;  // one holder, two for a straggler
    std::map<uint64_t, uint32_t> open_leases;        // lease serial -> units its holder still holds
    uint64_t stride = 0;                             // set_run_stride
    std::map<WorkerId, double> unit_seconds;  // per worker: its latest lease's seconds per unit
    std::set<std::string> blocked;            // workers or keys
    std::deque<double> durations;             // seconds of the latest units done
    int priority = 0;
    bool paused = false;
    uint64_t served = 0;  // lease_serial_ at its latest lease; 0: never leased
    std::string group;    // "" or the group it shares the farm with
    int64_t rank = 0;     // its order in the group
    uint64_t added = 0;   // its place in the order of addition
  };
  /// A group of jobs that share the farm as one (a sequence's frames).
  struct Group {
    int priority = 0;
    bool paused = false;
    size_t leases = 0;    // open leases of its jobs
    uint64_t served = 0;  // the latest of its jobs' `served`
    uint64_t added = 0;   // its place in the order of addition: its first job's
    std::set<std::pair<int64_t, std::string>> members;  // (rank, job)
  };
  /// How a job (or a group of jobs) stands for the next lease.
  struct Standing {
    int priority = 0;
    size_t leases = 0;
    uint64_t served = 0;
  };
  std::map<std::string, Job> jobs_;
  std::map<std::string, Group> groups_;
  // Jobs of their own and groups, in the order they were added (a group where its first job
  // was): what a lease looks at.
  struct Entry {
    std::string name;
    bool group = false;
  };
  std::map<uint64_t, Entry> order_;
  uint64_t added_ = 0;  // counts additions: Job::added, Group::added
  std::map<WorkerId, std::set<UnitRef>> by_worker_;  // leases per worker
  uint64_t lease_serial_ = 0;                        // counts leases: Job::served, Holder::lease

  void drop_lease(const WorkerId& worker, const UnitRef& unit);
  /// Ends holder `h`'s lease of `unit` (the holder is removed from `j.leased` by the caller).
  void unhold(Job& j, const Job::Holder& h, const UnitRef& unit);
  /// The next unit of `j` to lease (requeued first, then the lowest fresh one), taken out of the
  /// queue; nullopt when none is pending.
  static std::optional<uint64_t> take_pending(Job& j);
  /// Takes the first unit of `j`'s fresh range (not empty), skipping those taken ahead.
  static uint64_t take_fresh(Job& j);
  /// Takes `unit` out of `j`'s queue when it is pending there.
  static bool take_if_pending(Job& j, uint64_t unit);
  /// How many units `worker`'s next lease of `j` covers.
  static uint32_t run_length(const Job& j, const WorkerId& worker, const RunPolicy& runs);
  static bool has_pending(const Job& j);
  /// The job's group; nullptr for a job of its own.
  Group* group_of(const Job& j);
  const Group* group_of(const Job& j) const;
  /// The jobs that hold a lease now, by name (bounded by the leases out, not by the jobs).
  std::vector<const std::string*> leased_jobs() const;
  /// Whether the job gets no new leases (its own pause or its group's), and its priority (its
  /// group's for a job of a group).
  bool held(const Job& j) const;
  int priority_of(const Job& j) const;
  /// Records a new lease of `j` (serial, units) and counts it for its group.
  void open_lease(Job& j, uint64_t serial, uint32_t units);
  /// The job of `group` to serve `who` next: its lowest-ranked one not held or blocked with a unit
  /// pending; nullptr when none.
  const std::string* offer(const Group& group, const std::string& who) const;
  /// Whether `a` is served before `b` (both with units pending): priority, then fewer leases now,
  /// then served longer ago.
  static bool served_before(const Standing& a, const Standing& b);
  static double median(const std::deque<double>& values);
  /// The threshold past which a lease of `j` is a straggler; nullopt when the policy is off or
  /// the median is not trusted yet.
  static std::optional<double> straggler_threshold(const Job& j, const StragglerPolicy& policy);
};

}  // namespace rayfarm::master
