#pragma once
// Internal to rayfarm::net: the process's one ZeroMQ context, shared by every socket and by the
// ZAP handler (ZAP works only between sockets of the same context).
#include <zmq.hpp>

namespace rayfarm::net::detail {

/// The process's ZeroMQ context. Deliberately never destroyed: terminating a context waits for
/// every socket, and a process that exits must never wait on one still open elsewhere.
zmq::context_t& context();

}  // namespace rayfarm::net::detail
