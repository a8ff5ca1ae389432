#include "worker/connection.h"

#include <algorithm>
#include <stdexcept>
#include <thread>

#include "common/protocol/codec.h"
#include "common/util/log.h"

namespace rayfarm::worker {
using protocol::encode;
using std::chrono::milliseconds;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("worker"); }

/// How long a closing connection waits for its last messages to leave.
constexpr milliseconds kFinalLinger{2000};
/// How often at most a worker logs that messages to the master are dropped: a refused worker's
/// heartbeats are dropped every interval for as long as it is refused.
constexpr std::chrono::seconds kDroppedLogInterval{60};

double seconds_since(Connection::Clock::time_point t) {
  return std::chrono::duration<double>(Connection::Clock::now() - t).count();
}

}  // namespace

const char* Connection::state_name(State state) {
  switch (state) {
    case State::kClosed:
      return "closed";
    case State::kGreeting:
      return "greeting";
    case State::kWelcomed:
      return "welcomed";
    case State::kRefused:
      return "refused";
  }
  return "?";
}

const char* Connection::event_name(Event event) {
  switch (event) {
    case Event::kOpen:
      return "open";
    case Event::kGreetAgain:
      return "greet again";
    case Event::kWelcome:
      return "be welcomed";
    case Event::kRefuse:
      return "be refused";
    case Event::kClose:
      return "close";
  }
  return "?";
}

Connection::Connection(std::string endpoint, net::Curve curve, protocol::HeartbeatOptions heartbeat,
                       wire::Hello hello)
    : endpoint_(std::move(endpoint)),
      curve_(std::move(curve)),
      heartbeat_(heartbeat),
      hello_(std::move(hello)),
      backoff_(heartbeat_.reconnect_min),
      dropped_log_(kDroppedLogInterval) {}

Connection::~Connection() = default;

std::optional<Connection::State> Connection::after(State from, Event event) {
  using enum State;
  const bool connected = from == kGreeting || from == kWelcomed;
  switch (event) {
    case Event::kOpen:
      if (from == kClosed) return kGreeting;
      break;
    case Event::kGreetAgain:
      if (from == kWelcomed) return kGreeting;
      break;
    case Event::kWelcome:  // a repeated Welcome changes nothing
      if (connected) return kWelcomed;
      break;
    case Event::kRefuse:
      if (connected) return kRefused;
      break;
    case Event::kClose:
      if (connected) return kClosed;
      break;
  }
  return std::nullopt;
}

void Connection::enter(Event event) {
  const std::optional<State> next = after(state_, event);
  if (!next) {
    throw std::logic_error(std::string("the worker's connection cannot ") + event_name(event) +
                           " when " + state_name(state_));
  }
  log()->debug("connection to the master: {} -> {}", state_name(state_), state_name(*next));
  state_ = *next;
}

void Connection::open() {
  auto socket = std::make_unique<net::Dealer>(endpoint_, net::kDefaultMaxMessageBytes, curve_);
  enter(Event::kOpen);
  socket_ = std::move(socket);
  last_heard_ = Clock::now();
  next_heartbeat_ = last_heard_ + heartbeat_.interval;
  send(encode(hello_));
}

void Connection::greet_again() {
  enter(Event::kGreetAgain);
  send(encode(hello_));
}

void Connection::welcome() {
  enter(Event::kWelcome);
  backoff_ = heartbeat_.reconnect_min;
  for (const auto& frames : held_) send(frames);
  held_.clear();
}

void Connection::refuse() { enter(Event::kRefuse); }

void Connection::reconnect(const std::function<bool()>& cut_short) {
  log()->warn("the master at {} is silent for {:.1f} s; reconnecting in {:.1f} s", endpoint_,
              seconds_since(last_heard_), backoff_.count() / 1000.0);
  socket_.reset();
  enter(Event::kClose);
  const auto until = Clock::now() + backoff_;
  while (Clock::now() < until && !cut_short()) std::this_thread::sleep_for(milliseconds{20});
  backoff_ = std::min(backoff_ * 2, heartbeat_.reconnect_max);
  open();
}

void Connection::close() {
  if (socket_ && welcomed()) {
    wire::Goodbye bye;
    bye.set_reason("stopped");
    send(encode(std::move(bye)));
    socket_->set_linger(kFinalLinger);
  }
  socket_.reset();
  if (after(state_, Event::kClose)) enter(Event::kClose);
}

void Connection::send(const net::Frames& frames) {
  if (!socket_ || socket_->send(frames)) return;
  ++messages_dropped_;
  const LogThrottle::Verdict verdict = dropped_log_.occur();
  if (!verdict.log) return;
  if (welcomed()) {
    log()->warn("send queue to the master is full; message dropped{}",
                LogThrottle::suffix(verdict));
  } else {
    // No connection takes messages: the master refused this worker's key or security (or a
    // connection is being made again); check_handshake says which.
    log()->warn(
        "no connection to the master takes messages (it has not let this worker in); "
        "message dropped{}, logged at most every {} s",
        LogThrottle::suffix(verdict), kDroppedLogInterval.count());
  }
}

void Connection::send_when_welcomed(net::Frames frames) {
  if (welcomed()) {
    send(frames);
  } else {
    held_.push_back(std::move(frames));
  }
}

std::optional<net::Frames> Connection::receive(milliseconds wait) {
  if (!socket_) return std::nullopt;
  auto frames = socket_->receive(wait);
  if (frames) last_heard_ = Clock::now();
  return frames;
}

milliseconds Connection::until_heartbeat(Clock::time_point now) const {
  return std::chrono::duration_cast<milliseconds>(next_heartbeat_ - now);
}

void Connection::tick(Clock::time_point now) {
  if (now >= next_heartbeat_) {
    send(encode(wire::Heartbeat{}));
    next_heartbeat_ = now + heartbeat_.interval;
  }
  if (!welcomed()) check_handshake();
}

bool Connection::silent(Clock::time_point now) const {
  return now - last_heard_ > heartbeat_.expiry();
}

void Connection::check_handshake() {
  if (!socket_) return;
  const net::HandshakeStatus st = socket_->handshake();
  if (st.state == net::Handshake::kSucceeded) reported_handshake_.clear();
  if (st.state == net::Handshake::kSucceeded || st.state == net::Handshake::kPending) return;
  if (st.detail == reported_handshake_) return;
  reported_handshake_ = st.detail;
  log()->error("the master at {} did not let this worker in: {}{}; retrying", endpoint_, st.detail,
               st.state == net::Handshake::kRefused
                   ? " (add this worker's public key to the master's --worker-keys)"
                   : "");
}

}  // namespace rayfarm::worker
