#include "common/net/socket.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <iterator>

#include <fmt/format.h>

#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "common/net/context.h"
#include "common/net/keys.h"

namespace rayfarm::net {

namespace {
std::atomic<int> g_io_threads{1};
std::atomic<bool> g_context_made{false};
}  // namespace

zmq::context_t& detail::context() {
  static auto* ctx = [] {
    g_context_made = true;
    return new zmq::context_t(g_io_threads.load());
  }();
  return *ctx;
}

void set_io_threads(int threads) {
  if (threads < 1 || threads > 64) {
    throw NetError(fmt::format("I/O threads must be 1 to 64, got {}", threads));
  }
  if (g_context_made) throw NetError("I/O threads are set before the first socket is made");
  g_io_threads = threads;
}

namespace {
using detail::context;

/// How far a Dealer's automatic reconnections back off (from ZeroMQ's 100 ms), so that a peer
/// whose key is refused does not knock ten times a second.
constexpr int kReconnectMaxMs = 2000;

void configure(zmq::socket_t& socket, int64_t max_message_bytes) {
  socket.set(zmq::sockopt::linger, 0);
  socket.set(zmq::sockopt::maxmsgsize, max_message_bytes);
}

void check_key(const std::string& key, const char* what) {
  if (!is_key(key)) throw NetError(std::string(what) + " is not a 40-character Z85 CURVE key");
}

void configure_curve_server(zmq::socket_t& socket, const Curve& curve) {
  if (!curve.enabled()) return;
  if (!curve_available()) throw NetError("this libzmq has no CURVE support (libsodium)");
  check_key(curve.secret_key, "the secret key");
  socket.set(zmq::sockopt::curve_server, true);
  socket.set(zmq::sockopt::curve_secretkey, curve.secret_key);
  socket.set(zmq::sockopt::zap_domain, curve.zap_domain);
}

void configure_curve_client(zmq::socket_t& socket, const Curve& curve) {
  if (!curve.enabled()) return;
  if (!curve_available()) throw NetError("this libzmq has no CURVE support (libsodium)");
  check_key(curve.secret_key, "the secret key");
  check_key(curve.public_key, "the public key");
  check_key(curve.server_key, "the master's public key");
  socket.set(zmq::sockopt::curve_serverkey, curve.server_key);
  socket.set(zmq::sockopt::curve_publickey, curve.public_key);
  socket.set(zmq::sockopt::curve_secretkey, curve.secret_key);
}

/// What a Dealer says when the peer's security mechanism is not its own: which side has keys.
std::string mechanism_mismatch(bool curve) {
  return curve ? "the peer uses another security mechanism: this side has CURVE keys and the peer "
                 "runs --insecure (plain)"
               : "the peer uses another security mechanism: it has CURVE keys and this side runs "
                 "--insecure (give this side --key and --master-key)";
}

std::string protocol_error_cause(uint32_t code, bool curve) {
  switch (code) {
    case ZMQ_PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH:
      return mechanism_mismatch(curve);
    case ZMQ_PROTOCOL_ERROR_ZMTP_CRYPTOGRAPHIC:
      return "the CURVE handshake failed: the keys do not match (is the master's public key the "
             "right one?)";
    default:
      if (code >= ZMQ_PROTOCOL_ERROR_ZAP_UNSPECIFIED && code < ZMQ_PROTOCOL_ERROR_WS_UNSPECIFIED) {
        return fmt::format("the peer's authentication handler failed (error 0x{:x})", code);
      }
      return fmt::format("the security handshake failed (protocol error 0x{:x})", code);
  }
}

Frames to_frames(std::vector<zmq::message_t>& messages, size_t skip) {
  Frames frames;
  frames.reserve(messages.size() - skip);
  for (size_t i = skip; i < messages.size(); ++i) frames.push_back(messages[i].to_string());
  return frames;
}

/// Receives all frames of one message without waiting; empty when none is queued. A signal
/// interrupting the call counts as no message.
std::vector<zmq::message_t> receive_now(zmq::socket_t& socket) {
  std::vector<zmq::message_t> messages;
  try {
    if (!zmq::recv_multipart(socket, std::back_inserter(messages), zmq::recv_flags::dontwait)) {
      messages.clear();
    }
  } catch (const zmq::error_t& e) {
    if (e.num() != EINTR) throw;
    messages.clear();
  }
  return messages;
}

bool wait_readable(zmq::socket_t& socket, std::chrono::milliseconds timeout) {
  if (timeout.count() <= 0) return true;  // the caller tries a non-blocking receive
  std::vector<zmq::pollitem_t> items{{socket.handle(), 0, ZMQ_POLLIN, 0}};
  try {
    zmq::poll(items, timeout);
  } catch (const zmq::error_t& e) {
    if (e.num() != EINTR) throw;
    return false;
  }
  return (items[0].revents & ZMQ_POLLIN) != 0;
}

bool send_frames(zmq::socket_t& socket, const PeerId* peer, const Frames& frames) {
  std::vector<zmq::const_buffer> parts;
  parts.reserve(frames.size() + 1);
  if (peer) parts.push_back(zmq::buffer(*peer));
  for (const auto& f : frames) parts.push_back(zmq::buffer(f));
  try {
    return zmq::send_multipart(socket, parts, zmq::send_flags::dontwait).has_value();
  } catch (const zmq::error_t& e) {
    // EHOSTUNREACH: the peer is gone (ROUTER_MANDATORY); EAGAIN: queue full; EINTR: a signal.
    if (e.num() == EHOSTUNREACH || e.num() == EAGAIN || e.num() == EINTR) return false;
    throw;
  }
}

}  // namespace

std::string peer_label(const PeerId& peer) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(peer.size() * 2);
  for (unsigned char c : peer) {
    out.push_back(kHex[c >> 4]);
    out.push_back(kHex[c & 15]);
  }
  return out;
}

struct Socket::Impl {
  zmq::socket_t socket;
  std::string endpoint;
  // A Dealer's handshake events (a PAIR connected to the socket's monitor).
  zmq::socket_t monitor;
  bool in_handshake = false;  // connected, no handshake event yet
  HandshakeStatus handshake;
  bool curve = false;           // this side has CURVE keys
  bool mechanism_seen = false;  // a handshake failed on the mechanisms: the cause is known

  /// The connection was closed by the peer during the handshake, before any failure said why.
  /// Without CURVE keys this side has no key that could be wrong: a peer that hangs up on a plain
  /// handshake uses CURVE (a CURVE server reads the plain greeting and closes the connection,
  /// often before this side has read the greeting that would name its mechanism). With CURVE
  /// keys, a wrong server key and a plain peer both look like this, unless an earlier attempt
  /// showed the mechanisms differ.
  HandshakeStatus closed_in_handshake() const {
    if (!curve || mechanism_seen) {
      return {Handshake::kFailed,
              mechanism_mismatch(curve) + "; it closed the connection during the handshake"};
    }
    return {Handshake::kFailed,
            "the peer closed the connection during the CURVE handshake: the server's public key "
            "given to this side (--master-key) is probably wrong, or the peer uses another "
            "security mechanism (it runs --insecure)"};
  }

  ~Impl() {
    if (monitor) {
      zmq_socket_monitor(socket.handle(), nullptr, 0);
      monitor.close();
    }
  }

  void watch_handshakes() {
    static std::atomic<uint64_t> counter{0};
    const std::string address = "inproc://rayfarm-monitor-" + std::to_string(counter++);
    constexpr int kEvents = ZMQ_EVENT_CONNECTED | ZMQ_EVENT_DISCONNECTED |
                            ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL | ZMQ_EVENT_HANDSHAKE_SUCCEEDED |
                            ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL | ZMQ_EVENT_HANDSHAKE_FAILED_AUTH;
    if (zmq_socket_monitor(socket.handle(), address.c_str(), kEvents) != 0) throw zmq::error_t();
    monitor = zmq::socket_t(context(), zmq::socket_type::pair);
    monitor.set(zmq::sockopt::linger, 0);
    monitor.connect(address);
  }

  /// Reads the monitor's pending events into `handshake`.
  void read_events() {
    if (!monitor) return;
    while (true) {
      std::vector<zmq::message_t> parts;
      try {
        if (!zmq::recv_multipart(monitor, std::back_inserter(parts), zmq::recv_flags::dontwait))
          return;
      } catch (const zmq::error_t&) {
        return;
      }
      if (parts.empty() || parts[0].size() < 6) continue;
      uint16_t event = 0;
      uint32_t value = 0;
      std::memcpy(&event, parts[0].data(), 2);
      std::memcpy(&value, static_cast<const char*>(parts[0].data()) + 2, 4);
      switch (event) {
        case ZMQ_EVENT_CONNECTED:
          in_handshake = true;
          break;
        case ZMQ_EVENT_HANDSHAKE_SUCCEEDED:
          in_handshake = false;
          handshake = {Handshake::kSucceeded, ""};
          break;
        case ZMQ_EVENT_HANDSHAKE_FAILED_AUTH:
          in_handshake = false;
          handshake = {Handshake::kRefused,
                       fmt::format("authentication refused: the peer does not admit this key "
                                   "(status {})",
                                   value)};
          break;
        case ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL:
          in_handshake = false;
          if (value == ZMQ_PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH) mechanism_seen = true;
          handshake = {Handshake::kFailed, protocol_error_cause(value, curve)};
          break;
        case ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL:
          in_handshake = false;
          if (value == EPIPE || value == ECONNRESET) {
            handshake = closed_in_handshake();
            handshake.peer_closed = true;  // the master may be starting: the CLI tries again
          } else {
            handshake = {Handshake::kFailed,
                         fmt::format("the security handshake failed ({})", zmq_strerror(value)),
                         /*peer_closed=*/true};
          }
          break;
        case ZMQ_EVENT_DISCONNECTED:
          if (in_handshake && handshake.state != Handshake::kRefused &&
              handshake.state != Handshake::kFailed) {
            if (!curve || mechanism_seen) {
              handshake = {Handshake::kDropped,
                           "the peer closed the connection during the handshake: it probably "
                           "uses another security mechanism (" +
                               std::string(curve ? "this side has CURVE keys and it runs "
                                                   "--insecure"
                                                 : "it has CURVE keys and this side runs "
                                                   "--insecure") +
                               ")"};
            } else {
              handshake = {Handshake::kDropped,
                           "the peer closed the connection during the handshake: it did not "
                           "accept this socket's security (a wrong master public key, or the peer "
                           "uses another security mechanism: it runs --insecure)"};
            }
          }
          in_handshake = false;
          break;
        default:
          break;
      }
    }
  }
};

Socket::Socket(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Socket::~Socket() = default;
Socket::Socket(Socket&&) noexcept = default;
Socket& Socket::operator=(Socket&&) noexcept = default;

std::string Socket::endpoint() const { return impl_->endpoint; }

void Socket::set_linger(std::chrono::milliseconds linger) {
  impl_->socket.set(zmq::sockopt::linger, static_cast<int>(linger.count()));
}

Router::Router(const std::string& endpoint, int64_t max_message_bytes, const Curve& curve,
               QueueBounds queues)
    : Socket(std::make_unique<Impl>()) {
  try {
    impl_->socket = zmq::socket_t(context(), zmq::socket_type::router);
    configure(impl_->socket, max_message_bytes);
    impl_->socket.set(zmq::sockopt::sndhwm, queues.send);
    impl_->socket.set(zmq::sockopt::rcvhwm, queues.receive);
    configure_curve_server(impl_->socket, curve);
    impl_->socket.set(zmq::sockopt::router_mandatory, 1);
    impl_->socket.bind(endpoint);
    impl_->endpoint = impl_->socket.get(zmq::sockopt::last_endpoint);
  } catch (const zmq::error_t& e) {
    throw NetError("cannot bind " + endpoint + ": " + e.what());
  }
}

bool Router::send(const PeerId& peer, const Frames& frames) {
  return send_frames(impl_->socket, &peer, frames);
}

std::optional<Delivery> Router::receive(std::chrono::milliseconds timeout) {
  if (!wait_readable(impl_->socket, timeout)) return std::nullopt;
  auto messages = receive_now(impl_->socket);
  if (messages.empty()) return std::nullopt;
  Delivery d;
  d.peer = messages[0].to_string();
  d.frames = to_frames(messages, 1);
  // The routing frame is made by the ROUTER; the peer's own frames carry its metadata.
  if (const char* user = zmq_msg_gets(messages.back().handle(), "User-Id")) d.user = user;
  if (const char* key = zmq_msg_gets(messages.back().handle(), kKeyProperty)) d.key = key;
  return d;
}

Dealer::Dealer(const std::string& endpoint, int64_t max_message_bytes, const Curve& curve)
    : Socket(std::make_unique<Impl>()) {
  try {
    impl_->socket = zmq::socket_t(context(), zmq::socket_type::dealer);
    configure(impl_->socket, max_message_bytes);
    configure_curve_client(impl_->socket, curve);
    impl_->curve = curve.enabled();
    impl_->socket.set(zmq::sockopt::reconnect_ivl_max, kReconnectMaxMs);
    impl_->watch_handshakes();
    impl_->socket.connect(endpoint);
    impl_->endpoint = endpoint;
  } catch (const zmq::error_t& e) {
    throw NetError("cannot connect to " + endpoint + ": " + e.what());
  }
}

bool Dealer::send(const Frames& frames) { return send_frames(impl_->socket, nullptr, frames); }

std::optional<Frames> Dealer::receive(std::chrono::milliseconds timeout) {
  if (!wait_readable(impl_->socket, timeout)) return std::nullopt;
  auto messages = receive_now(impl_->socket);
  if (messages.empty()) return std::nullopt;
  return to_frames(messages, 0);
}

HandshakeStatus Dealer::handshake() {
  impl_->read_events();
  return impl_->handshake;
}

std::vector<bool> poll(std::span<Socket* const> sockets, std::chrono::milliseconds timeout) {
  std::vector<zmq::pollitem_t> items;
  items.reserve(sockets.size());
  for (Socket* s : sockets) items.push_back({s->impl_->socket.handle(), 0, ZMQ_POLLIN, 0});
  std::vector<bool> readable(sockets.size(), false);
  try {
    zmq::poll(items, std::max(timeout, std::chrono::milliseconds{0}));
  } catch (const zmq::error_t& e) {
    if (e.num() != EINTR) throw;
    return readable;
  }
  for (size_t i = 0; i < items.size(); ++i) readable[i] = (items[i].revents & ZMQ_POLLIN) != 0;
  return readable;
}

}  // namespace rayfarm::net
