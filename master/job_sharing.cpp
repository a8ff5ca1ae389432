// How a job shares the farm once accepted: its priority and whether it is paused (the scheduler
// acts on both; docs/farm.md, "Sharing the farm").
#include "common/limits.h"
#include "common/protocol/convert.h"
#include "master/job_manager.h"
#include "master/job_text.h"

namespace rayfarm::master {
using namespace detail;

const JobRecord* JobManager::change(const std::string& id, std::optional<int32_t> priority,
                                    std::optional<bool> paused, const std::string& by) {
  if (sequence_frames(id)) return change_sequence(id, priority, paused);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return nullptr;
  // A sequence shares the farm as one job, at one priority: its frames' is the sequence's.
  const JobSpec& spec = it->second.record.spec;
  if (priority && sequence_frames(spec.sequence)) {
    throw JobRejected(
        fmt::format("job {} is frame {} of sequence {}: give the sequence its priority", id,
                    spec.frame.value_or(0), spec.sequence));
  }
  return change_one(id, priority, paused, by);
}

const JobRecord* JobManager::change_one(const std::string& id, std::optional<int32_t> priority,
                                        std::optional<bool> paused, const std::string& by) {
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return nullptr;
  Job& job = it->second;
  JobRecord& r = job.record;
  if (!job.active || job.active->finishing) {
    throw JobRejected(r.unreadable ? "job " + id + " cannot be changed: " + r.error
                      : job.active
                          ? "job " + id +
                                " has rendered all it will: only its final image is left to "
                                "write"
                          : fmt::format("job {} is {}: only a queued or running job can be paused, "
                                        "resumed or given a priority",
                                        id, protocol::job_state_name(r.state)));
  }
  if (priority && (*priority < kMinPriority || *priority > kMaxPriority)) {
    throw JobRejected(fmt::format("priority {} is out of range ({} to {})", *priority, kMinPriority,
                                  kMaxPriority));
  }
  const auto now = Clock::now();
  // The job's log says what changed and who asked (a frame's, when its sequence changes, not).
  std::string what;
  if (priority && *priority != r.priority) {
    what = fmt::format("priority {} (was {})", *priority, r.priority);
    log_jobs()->info("job {}: priority {} (was {})", id, *priority, r.priority);
    r.priority = *priority;
    scheduler_.set_priority(id, r.priority);
  }
  if (paused && *paused != r.paused) {
    what += (what.empty() ? "" : ", ") + std::string(*paused ? "paused" : "resumed");
    r.paused = *paused;
    scheduler_.set_paused(id, r.paused);
    Sequence* q = sequence_of(r.spec);
    if (q != nullptr && r.paused) q->paused_alone.insert(id);
    if (q != nullptr && !r.paused) q->paused_alone.erase(id);
    if (r.paused || (q != nullptr && q->paused)) {  // a paused sequence keeps its clocks stopped
      job.active->pause(now);
    } else {
      job.active->resume(now);
    }
    const auto counts = scheduler_.counts(id);
    log_jobs()->info(
        "job {} {}{}", id, r.paused ? "paused" : "resumed",
        r.paused && counts.leased > 0
            ? fmt::format(": the {} unit{} out finish{}", counts.leased,
                          counts.leased == 1 ? "" : "s", counts.leased == 1 ? "es" : "")
            : std::string());
  }
  if (!what.empty()) note(r, "info", what + " by " + requester(by), /*routine=*/true);
  save(job);  // a failure is noted on the job and retried; the change holds meanwhile
  return &r;
}

}  // namespace rayfarm::master
