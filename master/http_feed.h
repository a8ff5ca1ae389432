#pragma once
// Between the master's reactor and its HTTP threads (http_server.h). The HTTP side never touches
// the reactor's state and the reactor never waits on the HTTP side:
// - the reactor publishes a snapshot of the farm (every job, every worker) at most twice a second,
//   and only while someone has looked in the last few seconds; HTTP reads take the latest one;
// - what needs the reactor (one job's full status, cancel, pause, resume, priority) is posted as
//   a call, which the reactor answers between two polls (within 100 ms); at most kMaxCalls wait,
//   so a flood of requests costs the reactor a bounded amount of work per turn.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "proto/rayfarm.pb.h"

namespace rayfarm::master {

struct FarmSnapshot {
  wire::JobList jobs;  ///< every job (sequences as one line), not filtered by key
  wire::WorkerList workers;
  std::chrono::steady_clock::time_point taken;
};

/// Who asks over HTTP: the client key its token names, or nobody.
struct HttpUser {
  bool authenticated = false;
  std::string key_name;  ///< "" on a master without keys
};

struct HttpAnswer {
  int status = 200;   ///< an HTTP status
  std::string error;  ///< why, when status is not 2xx
  std::shared_ptr<google::protobuf::Message> message;  ///< the reply, when 2xx
};

struct HttpCall {
  enum class Kind {
    kStatus,
    kCancel,
    kPause,
    kResume,
    kPriority,
    kRetry,
    kRemove,
    kDetail,
    kDrainWorker,
    kDisableWorker,
    kEnableWorker
  };
  Kind kind = Kind::kStatus;
  std::string job_id;  ///< the job's id; a worker's for the worker kinds
  HttpUser user;
  int32_t priority = 0;  ///< kPriority
};

class HttpFeed {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr size_t kMaxCalls = 64;
  /// A snapshot is published at most this often, and only while someone has looked within
  /// kWatchWindow.
  static constexpr auto kSnapshotInterval = std::chrono::milliseconds{500};
  static constexpr auto kWatchWindow = std::chrono::seconds{10};

  // The HTTP side.
  /// The latest snapshot; when it is older than kSnapshotInterval * 3 (nobody looked for a
  /// while), waits up to `wait` for a fresh one. nullptr before the first.
  std::shared_ptr<const FarmSnapshot> snapshot(std::chrono::milliseconds wait);
  /// Posts a call for the reactor; nullopt when kMaxCalls already wait (the master is busy).
  std::optional<std::future<HttpAnswer>> call(HttpCall call);

  // The reactor's side.
  /// Whether a snapshot is due: someone looked recently and the latest is old enough.
  bool snapshot_due(Clock::time_point now) const;
  void publish(FarmSnapshot snapshot);
  struct Pending {
    HttpCall call;
    std::promise<HttpAnswer> answer;
  };
  std::vector<Pending> take_calls();
  /// The reactor has stopped: calls waiting and to come are answered 503 at once, and snapshot()
  /// no longer waits.
  void close();

 private:
  mutable std::mutex mutex_;
  std::condition_variable published_;
  std::shared_ptr<const FarmSnapshot> snapshot_;
  Clock::time_point last_look_{};
  std::vector<Pending> calls_;
  bool closed_ = false;
};

}  // namespace rayfarm::master
