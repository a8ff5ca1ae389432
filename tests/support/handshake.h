#pragma once
// Waiting for a CURVE handshake to settle: tests poll the Dealer's status (bounded) instead of
// assuming the server answered within a fixed time.
#include <chrono>
#include <thread>

#include "common/net/socket.h"

namespace rayfarm::testing {

/// The Dealer's handshake once it is no longer pending, or still pending after `timeout`.
inline net::HandshakeStatus settled(net::Dealer& dealer,
                                    std::chrono::milliseconds timeout = std::chrono::seconds{10}) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  net::HandshakeStatus st = dealer.handshake();
  while (st.state == net::Handshake::kPending && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds{10});
    st = dealer.handshake();
  }
  return st;
}

}  // namespace rayfarm::testing
