#pragma once
// A ZeroMQ multipart message as plain bytes: one std::string per frame. Shared by the sockets
// (socket.h) and the codec (common/protocol/codec.h), so neither depends on the other.
#include <string>
#include <vector>

namespace rayfarm::net {

/// The frames of one multipart message, in order.
using Frames = std::vector<std::string>;

/// Routing id of a peer connected to a Router (opaque bytes chosen by ZeroMQ).
using PeerId = std::string;

/// A printable form of a peer id for logs: lowercase hex.
std::string peer_label(const PeerId& peer);

}  // namespace rayfarm::net
