#pragma once
// What a master is started with (rayfarm-master's flags): endpoints, data dir, heartbeats,
// security, limits and the job manager's options.
#include <chrono>
#include <filesystem>
#include <optional>
#include <set>
#include <string>

#include "common/net/keys.h"
#include "common/protocol/heartbeat.h"
#include "master/job_manager.h"
#include "master/peer_limits.h"

namespace rayfarm::master {

/// How the master's sockets are secured.
struct MasterSecurity {
  /// The master's key pair. Without one (the default) the sockets are plain, which the broker
  /// allows only on loopback endpoints: rayfarm-master --insecure.
  std::optional<net::KeyPair> key;
  std::filesystem::path worker_keys;  ///< allow-list of worker public keys (file or folder)
  std::filesystem::path client_keys;  ///< allow-list of client public keys (file or folder)
  /// Names of client keys (as in the clients' allow-list) that may cancel any job; every other
  /// key may cancel only the jobs it submitted.
  std::set<std::string> admin_clients;
  /// Keys that are neither the owner nor an admin cannot see a job either (status, list, fetch).
  bool private_jobs = false;
  /// Highest priority a client key that is not an admin may give a job (at submission or later),
  /// so that one key cannot push every other job aside; admins (and every client of a master
  /// without keys) may use the whole range, up to kMaxPriority.
  int32_t max_client_priority = 0;
};

/// ZAP domains of the two sockets: a key admitted in one is not admitted in the other.
inline constexpr const char* kWorkerDomain = "workers";
inline constexpr const char* kClientDomain = "clients";

struct MasterOptions {
  std::string worker_endpoint = "tcp://*:5555";
  std::string client_endpoint = "tcp://*:5556";
  std::filesystem::path data_dir = "rayfarm-data";
  /// The dashboard, its JSON API and /metrics: HOST:PORT, "" for none (http_server.h).
  std::string http_endpoint;
  /// http_endpoint is the default, not asked for: a port in use there is a warning (a second
  /// master on the machine runs without a dashboard), not a failure to start.
  bool http_endpoint_is_default = false;
  /// Jobs and workers may be read over HTTP without a token even on an endpoint beyond loopback
  /// (on loopback they always may).
  bool http_anonymous_read = false;
  protocol::HeartbeatOptions heartbeat;
  /// While results arrive, a job's image is rewritten at least this often.
  std::chrono::milliseconds image_interval{3000};
  MasterSecurity security;
  Limits limits;
  /// Checkpoints, failure limits and stragglers (the broker sets image_interval and worker_name).
  JobManagerOptions jobs;
};

}  // namespace rayfarm::master
