#include "master/access_gate.h"

#include "common/util/log.h"
#include "master/metrics.h"

namespace rayfarm::master {
namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("master"); }

/// Repeated refusals of the same key from the same address are logged at most this often.
constexpr auto kRefusalLogInterval = std::chrono::seconds{10};

}  // namespace

AccessGate::AccessGate(const MasterSecurity& security)
    : policy_({{kWorkerDomain, security.worker_keys}, {kClientDomain, security.client_keys}}),
      handler_([this](const net::ZapRequest& r) { return decide(r); }) {}

net::ZapVerdict AccessGate::decide(const net::ZapRequest& r) {
  const net::AllowListPolicy::Decision d = policy_.decide(r);
  if (!d.reload_note.empty()) {
    log()->log(d.reload_warning ? spdlog::level::warn : spdlog::level::info, "{}", d.reload_note);
  }
  if (d.admitted) return {true, d.name};
  metrics().refusals.add(r.domain == kWorkerDomain ? "worker_key" : "client_key");
  const char* role = r.domain == kWorkerDomain ? "worker" : "client";
  std::lock_guard lock(mutex_);
  if (recent_.size() > 4096) recent_.clear();
  const LogThrottle::Verdict verdict =
      recent_.try_emplace({r.domain, r.address, r.key}, kRefusalLogInterval).first->second.occur();
  if (verdict.log) {
    log()->warn("refused a {} connection from {}: {}{}", role, r.address, d.reason,
                LogThrottle::suffix(verdict));
  }
  return {};
}

std::optional<std::string> AccessGate::client_name_of(const std::string& key) {
  const net::AllowListPolicy::Decision d = policy_.admits_key(kClientDomain, key);
  if (!d.reload_note.empty()) {
    log()->log(d.reload_warning ? spdlog::level::warn : spdlog::level::info, "{}", d.reload_note);
  }
  if (!d.admitted) return std::nullopt;
  return d.name;
}

std::unique_ptr<AccessGate> AccessGate::open(const MasterOptions& options) {
  if (!options.security.key) {
    for (const std::string& endpoint : {options.worker_endpoint, options.client_endpoint}) {
      if (!net::is_loopback_endpoint(endpoint)) {
        throw std::runtime_error(
            "--insecure is allowed only on loopback endpoints, and " + endpoint +
            " is reachable from other machines: bind 127.0.0.1, or give the master its key and "
            "allow-lists (--key, --worker-keys, --client-keys; see docs/deploy.md)");
      }
    }
    log()->warn(
        "INSECURE: no authentication and no encryption on {} and {}; any local process can "
        "submit jobs or pose as a worker. Use keys (rayfarm keygen) for anything but a quick try",
        options.worker_endpoint, options.client_endpoint);
    return nullptr;
  }
  net::require_curve();
  if (options.security.worker_keys.empty() || options.security.client_keys.empty()) {
    throw net::KeyError(
        "the master needs an allow-list of worker keys (--worker-keys) and one of client keys "
        "(--client-keys): files or folders of public keys made by rayfarm keygen");
  }
  try {
    auto gate = std::make_unique<AccessGate>(options.security);
    log()->info("CURVE on both sockets, master key {}: {} worker key{} ({}), {} client key{} ({})",
                net::key_label(options.security.key->public_key), gate->policy_.size(kWorkerDomain),
                gate->policy_.size(kWorkerDomain) == 1 ? "" : "s",
                options.security.worker_keys.string(), gate->policy_.size(kClientDomain),
                gate->policy_.size(kClientDomain) == 1 ? "" : "s",
                options.security.client_keys.string());
    return gate;
  } catch (const net::NetError& e) {
    throw net::NetError(std::string("the master cannot authenticate its peers: ") + e.what());
  }
}

net::Curve curve_for(const MasterOptions& options, const char* domain) {
  net::Curve curve;
  if (options.security.key) {
    curve.public_key = options.security.key->public_key;
    curve.secret_key = options.security.key->secret_key;
    curve.zap_domain = domain;
  }
  return curve;
}

}  // namespace rayfarm::master
