#pragma once
// RAII sockets for the farm: a Router (the master binds one per endpoint) and a Dealer (workers
// and clients connect one). This module is the only one that includes zmq.hpp; nothing of ZeroMQ
// appears in its interface. Every socket has linger 0 (closing never blocks) and a message size
// limit; receives take a timeout and never block longer. Sockets use CURVE (authentication and
// encryption) when given keys (Curve), plain TCP otherwise; keys.h reads them, zap.h admits them.
#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/limits.h"
#include "common/net/frames.h"

namespace rayfarm::net {

/// A socket could not be created, bound or connected; the message names the endpoint and cause.
class NetError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Largest message (all frames) a socket accepts; a peer sending more is disconnected.
using rayfarm::kDefaultMaxMessageBytes;

/// CURVE settings of one socket, keys in Z85 (40 characters). A default Curve is a plain,
/// unauthenticated socket (what --insecure asks for).
struct Curve {
  std::string public_key;  ///< this side's public key
  std::string secret_key;  ///< this side's secret key
  std::string server_key;  ///< a Dealer's: the master's public key
  std::string zap_domain;  ///< a Router's: the ZAP domain its peers' keys are checked in
  bool enabled() const { return !secret_key.empty(); }
};

/// How many messages a Router queues per peer in each direction (ZeroMQ's high-water marks,
/// ZMQ_SNDHWM and ZMQ_RCVHWM, which apply to each connection separately). A send past the bound
/// fails (Router::send returns false) instead of growing the queue; a peer sending past it is
/// held back by TCP until the master has read what it sent.
struct QueueBounds {
  int send = 1000;
  int receive = 1000;
};

/// One message received on a Router: who sent it and its frames (the routing frame removed).
/// The message property in which the ZAP handler (zap.h) gives an admitted CURVE peer's public
/// key (Z85), beside its User-Id.
inline constexpr const char* kKeyProperty = "X-Key";

struct Delivery {
  PeerId peer;
  Frames frames;
  /// With CURVE, the name the ZAP handler gave the peer's key (its User-Id); else "".
  std::string user;
  /// With CURVE, the peer's public key (Z85) as the ZAP handler admitted it; else "".
  std::string key;
};

/// What a Dealer knows of its security handshake with the peer.
enum class Handshake {
  kPending,    ///< no handshake finished yet (the peer may be absent)
  kSucceeded,  ///< the last connection completed its handshake
  kRefused,    ///< the peer's ZAP handler refused this socket's key
  kFailed,     ///< a handshake failed: mechanism mismatch (one side --insecure), bad keys
  kDropped,    ///< the peer closed the connection during the handshake (e.g. a wrong server key)
};

/// The handshake state and, when it failed, a sentence naming the probable cause.
struct HandshakeStatus {
  Handshake state = Handshake::kPending;
  std::string detail;
  /// kFailed with no protocol error: the connection broke mid-handshake (the peer closed it:
  /// a wrong server key, or a peer, or a proxy in front of it, starting or stopping); retrying
  /// may succeed.
  bool peer_closed = false;
};

/// Common base: owns the ZeroMQ socket. Not copyable, movable.
class Socket {
 public:
  virtual ~Socket();
  Socket(const Socket&) = delete;
  Socket& operator=(const Socket&) = delete;
  Socket(Socket&&) noexcept;
  Socket& operator=(Socket&&) noexcept;

  /// The endpoint this socket is bound or connected to; for "tcp://*:0" the port chosen.
  std::string endpoint() const;
  /// How long closing waits to deliver queued messages (0 by default: closing never blocks).
  /// Set it before closing after a last message that must get out, e.g. a worker's goodbye.
  void set_linger(std::chrono::milliseconds linger);

 protected:
  struct Impl;
  explicit Socket(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  friend std::vector<bool> poll(std::span<Socket* const>, std::chrono::milliseconds);
};

/// A ZeroMQ ROUTER bound to an endpoint: receives from many peers, sends to one by id.
class Router : public Socket {
 public:
  /// Binds `endpoint` (e.g. "tcp://*:5555", "tcp://127.0.0.1:0") as a CURVE server when `curve`
  /// has keys: bind a ZapHandler (zap.h) first, or libzmq admits every key. Throws NetError.
  explicit Router(const std::string& endpoint, int64_t max_message_bytes = kDefaultMaxMessageBytes,
                  const Curve& curve = {}, QueueBounds queues = {});

  /// Sends `frames` to `peer` without blocking; false when the peer is gone or its queue is full.
  bool send(const PeerId& peer, const Frames& frames);
  /// Receives one message, waiting at most `timeout` (0 = do not wait); nullopt on timeout.
  std::optional<Delivery> receive(std::chrono::milliseconds timeout);
};

/// A ZeroMQ DEALER connected to an endpoint: talks to one master.
class Dealer : public Socket {
 public:
  /// Connects to `endpoint` (e.g. "tcp://localhost:5556"), as a CURVE client of
  /// `curve.server_key` when `curve` has keys; the connection is made in the background, so an
  /// absent peer shows up as receive timeouts. Throws NetError on a bad endpoint or key.
  explicit Dealer(const std::string& endpoint, int64_t max_message_bytes = kDefaultMaxMessageBytes,
                  const Curve& curve = {});

  /// Queues `frames` without blocking; false when the send queue is full.
  bool send(const Frames& frames);
  /// Receives one message, waiting at most `timeout` (0 = do not wait); nullopt on timeout.
  std::optional<Frames> receive(std::chrono::milliseconds timeout);
  /// How the security handshake went so far (reads the socket's events without waiting). A
  /// refusal or failure stays reported until a later handshake succeeds.
  HandshakeStatus handshake();
};

/// Waits until at least one of `sockets` has a message to read, or `timeout` passes. Returns,
/// for each socket, whether it is readable. An interrupted wait (a signal) returns all false.
std::vector<bool> poll(std::span<Socket* const> sockets, std::chrono::milliseconds timeout);

/// The I/O threads of the process's ZeroMQ context (1 unless set): they read and write the
/// sockets, and with CURVE encrypt and decrypt every message, each connection on one of them.
/// Must be called before the first socket is made; throws NetError afterwards or outside 1-64.
void set_io_threads(int threads);

}  // namespace rayfarm::net
