#pragma once
// The master's reactor: one thread owns both ROUTER sockets (workers, clients) and every timer.
// Workers say Hello, ask for work (WorkRequest) and get one unit per request; heartbeats flow both
// ways every interval; a worker silent for its liveness window is declared lost and its leased
// units are requeued. Clients send one request at a time and get one reply. Garbage on either
// socket is logged and ignored; a peer speaking another protocol version gets a Refusal.
// Both sockets use CURVE: a ZAP handler (access_gate.h), bound before them, admits on the worker
// socket only the keys of the workers' allow-list and on the client socket only those of the
// clients' list. The client socket's requests are handled in broker_clients.cpp; submissions are
// checked on a thread of their own (submission_queue.h).
// Submissions are checked against the limits (peer_limits.h) before their scene is loaded.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include "common/net/socket.h"
#include "common/util/log.h"
#include "master/access_gate.h"
#include "master/http_feed.h"
#include "master/http_server.h"
#include "master/http_tokens.h"
#include "master/job_manager.h"
#include "master/job_rights.h"
#include "master/job_store.h"
#include "master/log_budget.h"
#include "master/memory_return.h"
#include "master/master_options.h"
#include "master/metrics.h"
#include "master/submission_queue.h"
#include "master/worker_message_bounds.h"

namespace rayfarm::master {

/// The answer to a request that the client socket and the HTTP endpoint both serve: the reply,
/// or why not (code and text).
struct RequestAnswer {
  std::shared_ptr<google::protobuf::Message> reply;
  wire::Error::Code code = wire::Error::CODE_UNSPECIFIED;
  std::string error;
  std::string job_id;  ///< the job a refusal concerns
};

class Broker {
 public:
  /// Opens the data dir, reloads its jobs, binds the ZAP handler and then both endpoints. Throws
  /// std::runtime_error (net::NetError for an endpoint, net::KeyError for a key or allow-list)
  /// naming the cause, e.g. plain sockets asked for on an endpoint that is not loopback.
  explicit Broker(MasterOptions options);
  ~Broker();
  Broker(const Broker&) = delete;
  Broker& operator=(const Broker&) = delete;

  /// Serves until `stop` becomes true (checked at least every 100 ms).
  void run(const std::atomic<bool>& stop);

  /// The bound endpoints, with the ports chosen for "tcp://*:0".
  std::string worker_endpoint() const { return workers_socket_.endpoint(); }
  std::string client_endpoint() const { return clients_socket_.endpoint(); }
  /// The dashboard's address (http://HOST:PORT/); "" when the master serves no HTTP.
  std::string http_url() const { return http_ ? http_->url() : std::string(); }

  /// Wall time run() has spent outside its poll wait (handling messages, timers, dispatch), and
  /// the polls it made, since it started: busy_seconds over a window's wall time is the reactor's
  /// busy fraction. Safe to read from another thread while run() serves.
  double busy_seconds() const {
    return std::chrono::duration<double>(Clock::duration(busy_.load(std::memory_order_relaxed)))
        .count();
  }
  uint64_t polls() const { return polls_.load(std::memory_order_relaxed); }

 private:
  using Clock = std::chrono::steady_clock;
  /// How a worker takes part in the farm (ChangeWorker): draining and disabled workers get no
  /// units; a disabled one's were taken back. Ordered: the later, the stricter.
  enum class WorkerControl { kEnabled, kDraining, kDisabled };
  struct Worker {
    std::string name;
    WorkerControl control = WorkerControl::kEnabled;
    uint32_t threads = 0;
    Clock::time_point heard;    // its last message
    Clock::time_point expires;  // declared lost when silent until then
    Clock::duration forgiven{};  // time the master was busy, added to expires since `heard`
    uint32_t wants = 0;          // WorkRequests not answered yet
    // Bundles sent to it in the current window (kBundleWindow): when, and the bytes in all.
    std::set<std::string> bundles_sent;
    Clock::time_point bundle_window;
    uint64_t bundle_bytes = 0;
    // For `rayfarm workers`.
    std::string key_name;       // its key's name on the allow-list
    std::string build;          // its software version
    uint64_t units_merged = 0;  // its results merged
    double samples_merged = 0;  // their samples
    // From the start of its first merged unit to its last result: its rate is samples over this
    // (units rendered at once overlap, so their render times do not add up).
    Clock::time_point working_since, last_result;
  };

  /// The lines peers' messages cause, within a budget per kind and key (log_budget.h).
  LogBudget peer_logs_;

  WorkerMessageBounds message_bounds_;  // the largest message each worker connection may send
  MemoryReturn memory_return_;          // free memory given back after bursts

  MasterOptions options_;
  JobRights rights_;  // from options_.security
  JobStore store_;
  JobManager jobs_;
  std::unique_ptr<SubmissionQueue> submissions_;  // uses jobs_: destroyed before it
  std::unique_ptr<AccessGate> gate_;              // before the sockets: bound first, closed last
  net::Router workers_socket_;
  net::Router clients_socket_;
  std::map<net::PeerId, Worker> workers_;
  // The workers drained or disabled, by key and name: a worker that reconnects keeps its
  // control while the master runs. At most kRememberedControls.
  static constexpr size_t kRememberedControls = 1024;
  std::map<std::pair<std::string, std::string>, WorkerControl> controls_;
  // The HTTP endpoint (http_server.h): its tokens, what it sees of the farm, and the server,
  // last, so that it stops before the rest goes.
  HttpFeed http_feed_;
  std::unique_ptr<HttpTokens> tokens_;
  std::unique_ptr<HttpServer> http_;
  Clock::time_point next_heartbeat_;
  Clock::time_point listened_;  // when the sockets were last polled
  std::atomic<Clock::rep> busy_{0};  // busy_seconds(), in Clock ticks
  std::atomic<uint64_t> polls_{0};

  void handle_worker(const net::Delivery& delivery);
  /// Publishes a snapshot for the HTTP side when one is due, and answers its calls
  /// (broker_http.cpp).
  void serve_http();
  /// One HTTP call's answer; sets `changed` when a job's priority or pause changed.
  HttpAnswer answer_http(const HttpCall& call, bool& changed);
  void handle_client(const net::Delivery& delivery);
  void send_bundle(const net::PeerId& peer, Worker& w, const std::string& hash);
  /// Replies to the submissions whose checks have finished, admitting the accepted ones.
  void admit_submissions();
  /// Logs a line about a message from `peer` (its key: `key`, "" without CURVE) on `socket`
  /// ("worker" or "client"), within the budget of `kind` for that key (for that connection
  /// without keys); past the budget at trace level only.
  void peer_log(PeerLog kind, const std::string& socket, const net::PeerId& peer,
                const std::string& key, spdlog::level::level_enum level, const std::string& text);
  /// A warning about a peer's message (garbage, unexpected types, refusals), within its budget,
  /// prefixed with the socket's name.
  void complain(PeerLog kind, const std::string& socket, const net::Delivery& delivery,
                const std::string& text);
  /// The connected workers; for client key `user` (when given) with the units of the jobs it may
  /// not see left out.
  wire::WorkerList worker_list(const std::string* user = nullptr) const;
  wire::WorkerInfo worker_info(const net::PeerId& peer, const Worker& w,
                               const std::string* user) const;

  /// Requests that the client socket and the HTTP endpoint both serve (broker_requests.cpp).
  /// `user` is the client key's name; nullptr for an HTTP reader without a token.
  RequestAnswer job_detail(const std::string& id, const std::string* user) const;
  /// Drains, disables or enables a worker; sets `changed` when a worker may take units again.
  RequestAnswer change_worker(const wire::ChangeWorker& request, const std::string* user,
                              bool& changed);
  /// Gives a fetched job image the samples per pixel of the image itself (its EXR's header says),
  /// the job's own beside them, and why they differ when they do.
  void describe_image(wire::ImageData& image, uint32_t worker_count) const;
  void register_worker(const net::PeerId& peer, const wire::Hello& hello,
                       const std::string& key_name);
  /// How a worker went: lost (silent for its liveness window: logged as a warning) or any other
  /// way (it said goodbye, was refused, or its connection is gone).
  enum class Departure { kLeft, kLost };
  void remove_worker(const net::PeerId& peer, const std::string& why,
                     Departure departure = Departure::kLeft);
  void dispatch();
  void send_worker(const net::PeerId& peer, const net::Frames& frames);
  void reply(const net::PeerId& peer, const net::Frames& frames);
  void on_timers();
  void heard_from(Worker& w);
  std::string worker_label(const net::PeerId& peer) const;
  /// Whether client key `user` may cancel (may_manage) or see (may_see) a job of `owner`.
  bool may_manage(const std::string& owner, const std::string& user) const {
    return rights_.may_manage(owner, &user);
  }
  bool may_see(const std::string& owner, const std::string& user) const {
    return rights_.may_see(owner, &user);
  }
  /// Why client key `user` may not give a job `priority` (MasterSecurity::max_client_priority);
  /// nullopt when it may.
  std::optional<std::string> priority_refusal(int32_t priority, const std::string& user) const;
};

}  // namespace rayfarm::master
