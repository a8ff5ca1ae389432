#pragma once
// How large a message each worker connection may send: what the units leased to it can hold, not
// the socket's global maximum (--max-message-mb, which bundles from clients need). A worker's only
// large message is a unit's result, whose size its tile bounds (unit_result_bytes()); everything
// else it sends (hello, heartbeats, requests, failure reports) is small. The bound of a connection
// is the largest result of any unit ever leased to it, kept after it is lost so that a late result
// still fits, or kSmallMessageBytes for one that was never leased a unit. A message over its
// connection's bound is dropped before it is decoded, so that it is never held twice.
#include <cstdint>
#include <map>
#include <set>

#include "common/net/socket.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master {

class WorkerMessageBounds {
 public:
  /// The most a connection that holds no lease may send.
  static constexpr uint64_t kSmallMessageBytes = uint64_t{1} << 20;
  /// Connections remembered; past it, those not connected any more are forgotten.
  static constexpr size_t kMaxRemembered = 4096;

  /// `peer` was leased `unit`: its result may be as large as the unit's tile allows.
  void leased(const net::PeerId& peer, const wire::WorkUnit& unit);
  /// The most bytes `peer` may send in one message.
  uint64_t bound(const net::PeerId& peer) const;
  /// Forgets the connections not in `connected` once more than kMaxRemembered are kept.
  template <typename Map>
  void prune(const Map& connected) {
    if (bounds_.size() <= kMaxRemembered) return;
    for (auto it = bounds_.begin(); it != bounds_.end();) {
      it = connected.count(it->first) ? std::next(it) : bounds_.erase(it);
    }
  }

 private:
  std::map<net::PeerId, uint64_t> bounds_;
};

}  // namespace rayfarm::master
