#pragma once
// The worker's loop (the reliable-worker pattern): a DEALER socket to the master, Hello, then one
// WorkRequest per unit, with at most `units_in_flight` units asked for or in hand. Units render on
// threads of their own inside one TBB arena of the chosen size, so heartbeats keep flowing while
// they render. A bundle the worker lacks is fetched from the master and cached; the Renderer of
// the current job is kept between units. When the master is silent for its liveness window the
// worker reconnects with exponential back-off. Stopping finishes the unit in hand, returns its
// result and says goodbye.
//
// The parts: the reactor (agent.cpp) reads the master's messages and decides; the connection
// (connection.h) holds the socket, the heartbeats, the reconnections and the connection's state;
// the bundle cache (bundle_cache.h) keeps the scene bundles and the units waiting for one; the
// unit runner (unit_runner.h) renders units on its threads.
#include <atomic>
#include <cstdint>
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>

#include "common/net/socket.h"
#include "common/protocol/heartbeat.h"

namespace rayfarm::worker {

struct AgentOptions {
  std::string master = "tcp://localhost:5555";  ///< the master's worker endpoint
  uint32_t threads = 0;                         ///< render threads; 0 = all hardware threads
  std::filesystem::path cache_dir = "rayfarm-cache";
  std::string name;  ///< for the master's logs; "" = host-pid
  /// Units rendered at once, sharing the threads, so that one unit's last rows overlap the next
  /// unit's first; 0 = 2 with two or more threads, else 1.
  uint32_t units_in_flight = 0;
  protocol::HeartbeatOptions heartbeat;
  /// How long a stopping worker (SIGTERM) waits for the units in hand to finish and go back to
  /// the master; past it, its goodbye hands them back and the master requeues them. Keep it,
  /// plus 2 s for the last messages, within the time the deployment waits before SIGKILL.
  std::chrono::milliseconds stop_grace{8000};
  /// This worker's key pair and the master's public key; empty for a plain socket (--insecure),
  /// which `run` allows only to a loopback endpoint.
  net::Curve curve;
};

class Agent {
 public:
  /// Throws std::runtime_error when the cache dir cannot be created.
  explicit Agent(AgentOptions options);
  ~Agent();
  Agent(const Agent&) = delete;
  Agent& operator=(const Agent&) = delete;

  /// Serves the master until `stop` becomes true; returns 0 after a clean stop, 1 when the master
  /// refused this worker (another protocol version), the endpoint is invalid, or a plain socket
  /// was asked for on an endpoint that is not loopback. A refused key is logged and retried.
  int run(const std::atomic<bool>& stop);

  /// Units rendered and returned so far.
  uint64_t units_rendered() const;
  /// Messages to the master dropped so far because the socket would not take them (its send
  /// queue is full, or no connection takes messages, as when the master refused this worker).
  uint64_t messages_dropped() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// "<hostname>-<pid>": a worker's default name.
std::string default_worker_name();

}  // namespace rayfarm::worker
