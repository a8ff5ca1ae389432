#pragma once
// Submissions waiting to be checked: the limits, the bundle unpacked, the scene loaded, the
// reference read and the job stored (JobManager::prepare), on a thread of its own, so that the
// reactor keeps serving heartbeats and results meanwhile and admits each job once it is ready.
// What one peer can make it hold is bounded (docs/reliability.md, "Limits").
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/net/socket.h"
#include "master/job_manager.h"
#include "master/peer_limits.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master {

/// Submissions waiting to be checked (or being checked), in all, from one connection and from one
/// key; more are refused as busy (the CLI tries again).
inline constexpr size_t kMaxSubmissionsInFlight = 16;
inline constexpr size_t kMaxSubmissionsPerPeer = 1;
inline constexpr size_t kMaxSubmissionsPerKey = 4;

class SubmissionQueue {
 public:
  struct Done {
    net::PeerId peer;
    std::string label;  // the client, for the log
    std::string scene;  // the scene path, printable, for the log
    std::optional<JobManager::PreparedJob> job;
    std::string error;  // why it was refused
    std::string user;   // the client's key
    uint64_t bytes = 0;
    bool internal = false;  // refused for a fault of the master's, not of the submission
    uint64_t jobs = 1;      // jobs it would add: a sequence's frames
  };

  /// Starts the checking thread; `jobs` must outlive the queue.
  SubmissionQueue(const JobManager& jobs, Limits limits);
  /// Finishes the submission being checked, drops those waiting and joins the thread.
  ~SubmissionQueue();
  SubmissionQueue(const SubmissionQueue&) = delete;
  SubmissionQueue& operator=(const SubmissionQueue&) = delete;

  /// Queues a submission of `bytes` (its bundle's); false when too many are waiting: in all, from
  /// `peer` or from its key `user`, or in bytes (twice the bundle limit, one always fits).
  bool add(const net::PeerId& peer, std::string label, std::string user, wire::SubmitJob job,
           uint64_t bytes);
  /// The submissions checked since the last call.
  std::vector<Done> take_done();
  /// Submissions queued or being checked.
  size_t in_flight() const;
  /// The jobs they would add if accepted (a sequence counts its frames).
  uint64_t jobs_in_flight() const;
  /// Waits until every queued submission is checked.
  void drain();

 private:
  struct Task {
    net::PeerId peer;
    std::string label;
    std::string user;
    wire::SubmitJob job;
    uint64_t bytes = 0;
    uint64_t jobs = 1;
  };
  const JobManager& jobs_;
  const Limits limits_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, idle_;
  std::deque<Task> queue_;
  std::vector<Done> done_;
  std::map<net::PeerId, size_t> per_peer_;
  std::map<std::string, size_t> per_key_;
  size_t in_flight_ = 0;
  uint64_t jobs_in_flight_ = 0;
  uint64_t bytes_ = 0;
  bool busy_ = false;
  bool stop_ = false;
  std::thread thread_;  // last: starts once the rest is ready

  void loop();
};

}  // namespace rayfarm::master
