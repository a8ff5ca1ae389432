#pragma once
// The ZAP handler (ZeroMQ RFC 27): libzmq asks it, for every CURVE connection to a server socket
// of this process, whether the peer's public key may come in. Without a handler bound, libzmq
// admits every key, so the master binds one before its sockets and refuses to start without it.
// The handler serves on its own thread; the decision is a policy function given by the owner.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/net/keys.h"

namespace rayfarm::net {

/// One connection asking to be admitted.
struct ZapRequest {
  std::string domain;     ///< the ZAP domain of the server socket (Curve::zap_domain)
  std::string address;    ///< the peer's IP address
  std::string mechanism;  ///< "CURVE" (or "NULL", "PLAIN" for sockets without keys)
  std::string key;        ///< with CURVE, the peer's public key in Z85; else ""
};

/// A policy's answer: admitted with a name for the peer (its User-Id on every message), or
/// refused.
struct ZapVerdict {
  bool admitted = false;
  std::string user;
};

using ZapPolicy = std::function<ZapVerdict(const ZapRequest&)>;

/// Address every ZAP handler binds (RFC 27).
inline constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";

class ZapHandler {
 public:
  /// Binds kZapEndpoint on the process's context and starts answering with `policy` (called on
  /// the handler's thread; an exception refuses the peer). Throws NetError when the handler
  /// cannot be bound, e.g. another one is bound already.
  explicit ZapHandler(ZapPolicy policy);
  /// Stops the thread and unbinds.
  ~ZapHandler();
  ZapHandler(const ZapHandler&) = delete;
  ZapHandler& operator=(const ZapHandler&) = delete;

  /// Requests answered so far, and how many of them were refused.
  uint64_t requests() const { return requests_.load(); }
  uint64_t refusals() const { return refusals_.load(); }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::atomic<uint64_t> requests_{0}, refusals_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;

  void serve();
};

/// Admits a key when the allow-list of the request's ZAP domain lists it. Each list is a file or a
/// folder (AllowList::load), read again at most once per `reload_interval` while connections
/// come, so that a key file added to a folder admits its peer without a restart and a removed one
/// refuses the peer's next connection. A reload applies every key it can read: a file or line that
/// cannot be read is skipped (its keys are not admitted) and reported as a warning, once for as
/// long as the same files stay unreadable; only a list whose path cannot be read at all keeps its
/// previous keys. Thread-safe.
class AllowListPolicy {
 public:
  /// What `decide` concluded, with what the owner may want to log.
  struct Decision {
    bool admitted = false;
    std::string name;         ///< the key's name in its list, when admitted
    std::string reason;       ///< why it was refused
    std::string reload_note;  ///< a list was read again and changed, or could not all be read
    /// `reload_note` reports a file, line or list that could not be read (log it as a warning);
    /// false when it only reports a change.
    bool reload_warning = false;
  };

  /// Reads every domain's list now. Throws KeyError naming a bad file or line.
  explicit AllowListPolicy(std::map<std::string, std::filesystem::path> lists,
                           std::chrono::milliseconds reload_interval = std::chrono::seconds{1});

  Decision decide(const ZapRequest& request);
  /// Whether `domain`'s list (read again when due, as decide() does) still lists `key` (Z85):
  /// admitted, with the name it lists the key under, only when it does; reload_note as decide()
  /// reports it.
  Decision admits_key(const std::string& domain, const std::string& key);
  /// Keys in `domain`'s list (0 for an unknown domain).
  size_t size(const std::string& domain) const;

 private:
  struct Domain {
    std::filesystem::path path;
    AllowList keys;
    std::vector<std::string> problems;  // what the last reload could not read
  };
  mutable std::mutex mutex_;
  std::map<std::string, Domain> domains_;
  std::chrono::milliseconds reload_interval_;
  std::chrono::steady_clock::time_point loaded_;

  void reload(Decision& out);  // mutex held
  void reload_if_due(Decision& out);  // mutex held: reload() once reload_interval_ has passed
};

}  // namespace rayfarm::net
