#pragma once
// Liveness on the wire (the reliable-worker pattern): each side sends a Heartbeat every
// `interval` when it has sent nothing else, and declares its peer lost after `liveness` intervals
// without hearing from it. A worker that loses the master reconnects after a back-off that doubles
// from `reconnect_min` up to `reconnect_max`. The defaults live here, side by side; the services
// take them as options so that tests can shorten them.
#include <chrono>

namespace rayfarm::protocol {

using Millis = std::chrono::milliseconds;

inline constexpr Millis kHeartbeatInterval{1000};
/// Intervals of silence before a peer is declared lost (3 s with the default interval).
inline constexpr int kHeartbeatLiveness = 3;
inline constexpr Millis kReconnectMin{500};
inline constexpr Millis kReconnectMax{16000};

struct HeartbeatOptions {
  Millis interval = kHeartbeatInterval;
  int liveness = kHeartbeatLiveness;
  Millis reconnect_min = kReconnectMin;
  Millis reconnect_max = kReconnectMax;

  /// Silence after which the peer is declared lost.
  Millis expiry() const { return interval * liveness; }
};

}  // namespace rayfarm::protocol
