#pragma once
// A test's side of a master socket: the next message that is not a heartbeat, and a Hello.
#include <chrono>
#include <optional>

#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master::test_peer {

/// The first message within `timeout` that is not a heartbeat, decoded.
inline std::optional<protocol::Decoded> next(
    net::Dealer& d, std::chrono::milliseconds timeout = std::chrono::milliseconds{5000}) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (auto frames = d.receive(std::chrono::milliseconds{50})) {
      protocol::Decoded m = protocol::decode(*frames);
      if (!m.as<wire::Heartbeat>()) return m;
    }
  }
  return std::nullopt;
}

inline wire::Hello hello(wire::Role role) {
  wire::Hello h;
  h.set_role(role);
  h.set_name("test");
  return h;
}

}  // namespace rayfarm::master::test_peer
