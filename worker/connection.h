#pragma once
// The worker's connection to the master: its DEALER socket, heartbeats both ways, reconnection
// with exponential back-off, and the connection's state. Every change of state goes through
// enter(), and after() is the one table of the transitions:
//
//   kClosed --open--> kGreeting --welcome--> kWelcomed
//      ^               |  ^                     |
//      |               |  +----greet again------+   (the master forgot this worker)
//      +----close------+------------------------+   (reconnect(): close, back-off, open)
//   kGreeting or kWelcomed --refuse--> kRefused (final: another protocol version)
//
// What a message means for the worker is the reactor's business (worker/agent.cpp); this class
// only moves, sends and receives. Not thread-safe, except messages_dropped().
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "common/net/socket.h"
#include "common/protocol/heartbeat.h"
#include "common/util/log_throttle.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::worker {

class Connection {
 public:
  using Clock = std::chrono::steady_clock;

  enum class State {
    kClosed,    ///< no socket: before open(), during a reconnection's back-off, after close()
    kGreeting,  ///< Hello sent, no Welcome yet: messages may be dropped, work is not asked for
    kWelcomed,  ///< the master knows this worker
    kRefused,   ///< the master will not talk to this worker (another protocol version): final
  };
  static const char* state_name(State state);

  /// What moves the connection from one state to another (the public calls below).
  enum class Event { kOpen, kGreetAgain, kWelcome, kRefuse, kClose };
  static const char* event_name(Event event);
  /// The state `event` leads to from `from`, or none when the diagram has no such arrow.
  static std::optional<State> after(State from, Event event);

  /// `hello` is said on every new connection and whenever the master forgot this worker.
  Connection(std::string endpoint, net::Curve curve, protocol::HeartbeatOptions heartbeat,
             wire::Hello hello);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  State state() const { return state_; }
  bool welcomed() const { return state_ == State::kWelcomed; }
  bool refused() const { return state_ == State::kRefused; }
  const std::string& endpoint() const { return endpoint_; }

  // --- Transitions (see the diagram above) ---

  /// kClosed -> kGreeting: opens the socket and says Hello. Throws net::NetError for an endpoint
  /// or key the socket does not take.
  void open();
  /// kWelcomed -> kGreeting: says Hello again on the same socket.
  void greet_again();
  /// kGreeting -> kWelcomed: the back-off starts over and the messages held for the master leave.
  void welcome();
  /// -> kRefused.
  void refuse();
  /// kGreeting or kWelcomed -> kClosed -> kGreeting: closes the socket, waits the back-off (in
  /// short steps, leaving early once `cut_short` says so), doubles it, and opens again.
  void reconnect(const std::function<bool()>& cut_short);
  /// Says Goodbye when welcomed, gives the last messages a moment to leave, and closes the
  /// socket (-> kClosed, unless refused).
  void close();

  // --- Messages ---

  /// Sends now; a message the socket does not take is dropped, counted and logged (throttled).
  void send(const net::Frames& frames);
  /// Sends now when welcomed; otherwise holds the message until the next Welcome (results).
  void send_when_welcomed(net::Frames frames);
  /// The master's next message, waiting up to `wait`. Any message is a sign of life.
  std::optional<net::Frames> receive(std::chrono::milliseconds wait);

  // --- Time ---

  /// How long until the next heartbeat is due.
  std::chrono::milliseconds until_heartbeat(Clock::time_point now = Clock::now()) const;
  /// Sends a Heartbeat when one is due; until welcomed, logs a failed security handshake once
  /// per cause (the socket keeps retrying it by itself).
  void tick(Clock::time_point now = Clock::now());
  /// Whether the master has been silent for its liveness window.
  bool silent(Clock::time_point now = Clock::now()) const;

  /// Messages dropped so far because the socket would not take them.
  uint64_t messages_dropped() const { return messages_dropped_.load(); }

 private:
  std::string endpoint_;
  net::Curve curve_;
  protocol::HeartbeatOptions heartbeat_;
  wire::Hello hello_;

  State state_ = State::kClosed;
  std::unique_ptr<net::Dealer> socket_;
  Clock::time_point last_heard_;
  Clock::time_point next_heartbeat_;
  std::chrono::milliseconds backoff_;
  std::deque<net::Frames> held_;    // sent after the next Welcome
  std::string reported_handshake_;  // the handshake failure logged last
  LogThrottle dropped_log_;         // messages the socket would not take
  std::atomic<uint64_t> messages_dropped_{0};

  /// The one place the state changes: to after(state, event); throws std::logic_error when the
  /// diagram has no such arrow.
  void enter(Event event);
  void check_handshake();
};

}  // namespace rayfarm::worker
