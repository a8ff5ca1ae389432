#pragma once
// Who may connect to the master: the ZAP handler that admits, on the worker socket, only the keys
// of the workers' allow-list and, on the client socket, only those of the clients' list; and the
// CURVE settings of each socket. Every refusal is logged with the peer's address (repeats of the
// same refusal at most every 10 s).
#include <map>
#include <memory>
#include <optional>
#include <mutex>
#include <string>
#include <tuple>

#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/net/zap.h"
#include "common/util/log_throttle.h"
#include "master/master_options.h"

namespace rayfarm::master {

class AccessGate {
 public:
  /// The gate for `options`: null for plain sockets (allowed only on loopback endpoints, with a
  /// warning); otherwise a ZAP handler over both allow-lists, bound before any socket. Throws
  /// std::runtime_error (net::KeyError, net::NetError) naming what is missing or wrong.
  static std::unique_ptr<AccessGate> open(const MasterOptions& options);

  explicit AccessGate(const MasterSecurity& security);
  AccessGate(const AccessGate&) = delete;
  AccessGate& operator=(const AccessGate&) = delete;

  /// The name the clients' allow-list lists `key` (Z85) under now (an HTTP token's key),
  /// nullopt when it does not list it. Thread-safe.
  std::optional<std::string> client_name_of(const std::string& key);

 private:
  net::AllowListPolicy policy_;
  std::mutex mutex_;  // guards `recent_` (the ZAP thread only, but cheap to be sure)
  std::map<std::tuple<std::string, std::string, std::string>, LogThrottle> recent_;
  net::ZapHandler handler_;  // last: answers requests once the rest is ready

  net::ZapVerdict decide(const net::ZapRequest& r);
};

/// The CURVE settings of the socket of ZAP domain `domain` (kWorkerDomain or kClientDomain):
/// none without a master key.
net::Curve curve_for(const MasterOptions& options, const char* domain);

}  // namespace rayfarm::master
