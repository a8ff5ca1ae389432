#pragma once
// The replies both of the master's sockets send: an Error with its code, and the Refusal of a
// peer that speaks another protocol version.
#include <string>

#include <fmt/format.h>

#include "common/net/frames.h"
#include "common/protocol/codec.h"
#include "common/protocol/version.h"

namespace rayfarm::master {

inline net::Frames error_frames(wire::Error::Code code, const std::string& message,
                                const std::string& job_id = "") {
  wire::Error e;
  e.set_code(code);
  e.set_message(message);
  e.set_job_id(job_id);
  return protocol::encode(std::move(e));
}

/// The one answer to a request for a job that does not exist and, under --private-jobs, to one
/// for another key's job: the same bytes for both, so that the other key's job does not leak.
inline std::string no_such_job(const std::string& id, bool private_jobs) {
  return "unknown job '" + protocol::printable(id) + "'" +
         (private_jobs ? " (this master keeps jobs private to the key that submitted them)" : "");
}

inline net::Frames refusal_frames(uint32_t peer_version, const char* peer_kind) {
  wire::Refusal r;
  r.set_master_version(protocol::kProtocolVersion);
  r.set_peer_version(peer_version);
  r.set_reason(
      fmt::format("protocol version mismatch: the master speaks version {}, the {} sent "
                  "version {}",
                  protocol::kProtocolVersion, peer_kind, peer_version));
  return protocol::encode(std::move(r));
}

}  // namespace rayfarm::master
