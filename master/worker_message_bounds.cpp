#include "master/worker_message_bounds.h"

#include <algorithm>

#include "master/peer_limits.h"

namespace rayfarm::master {

void WorkerMessageBounds::leased(const net::PeerId& peer, const wire::WorkUnit& unit) {
  const auto& t = unit.tile();
  const uint64_t w = t.x1() > t.x0() ? uint64_t{t.x1()} - t.x0() : 0;
  const uint64_t h = t.y1() > t.y0() ? uint64_t{t.y1()} - t.y0() : 0;
  uint64_t& b = bounds_[peer];
  b = std::max(b, unit_result_bytes(w, h));
}

uint64_t WorkerMessageBounds::bound(const net::PeerId& peer) const {
  const auto it = bounds_.find(peer);
  return std::max(kSmallMessageBytes, it == bounds_.end() ? 0 : it->second);
}

}  // namespace rayfarm::master
