#include "common/net/socket.h"

#include <algorithm>
#include <cerrno>
#include <iterator>

#include <zmq.hpp>
#include <zmq_addon.hpp>

namespace rayfarm::net {
namespace {

/// The process's ZeroMQ context. Deliberately never destroyed: terminating a context waits for
/// every socket, and a process that exits must never wait on one still open elsewhere.
zmq::context_t& context() {
  static auto* ctx = new zmq::context_t(1);
  return *ctx;
}

void configure(zmq::socket_t& socket, int64_t max_message_bytes) {
  socket.set(zmq::sockopt::linger, 0);
  socket.set(zmq::sockopt::maxmsgsize, max_message_bytes);
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
};

Socket::Socket(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Socket::~Socket() = default;
Socket::Socket(Socket&&) noexcept = default;
Socket& Socket::operator=(Socket&&) noexcept = default;

std::string Socket::endpoint() const { return impl_->endpoint; }

void Socket::set_linger(std::chrono::milliseconds linger) {
  impl_->socket.set(zmq::sockopt::linger, static_cast<int>(linger.count()));
}

Router::Router(const std::string& endpoint, int64_t max_message_bytes)
    : Socket(std::make_unique<Impl>()) {
  try {
    impl_->socket = zmq::socket_t(context(), zmq::socket_type::router);
    configure(impl_->socket, max_message_bytes);
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
  return d;
}

Dealer::Dealer(const std::string& endpoint, int64_t max_message_bytes)
    : Socket(std::make_unique<Impl>()) {
  try {
    impl_->socket = zmq::socket_t(context(), zmq::socket_type::dealer);
    configure(impl_->socket, max_message_bytes);
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
