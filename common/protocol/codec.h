#pragma once
// The one codec of the wire. A message travels as two frames: its type (the protobuf full name,
// e.g. "rayfarm.wire.Hello") and its serialized body. encode() stamps the protocol version into
// the message (field 1 of every wire message); decode() checks the frame count, the type name, the
// sizes and the body, and throws DecodeError naming what was wrong. Garbage never crashes it.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

#include <google/protobuf/message.h>

#include "common/net/frames.h"
#include "common/protocol/version.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::protocol {

namespace wire = ::rayfarm::wire;

/// Largest type frame accepted.
inline constexpr size_t kMaxTypeBytes = 128;
/// Largest body accepted (bundles and images are the big ones).
inline constexpr size_t kMaxBodyBytes = size_t{1} << 30;  // 1 GiB

/// Frames that are not a valid wire message. what() names the cause; kind() classifies it.
class DecodeError : public std::runtime_error {
 public:
  enum class Kind { kFrameCount, kTooLarge, kUnknownType, kMalformedBody };
  DecodeError(Kind kind, const std::string& what) : std::runtime_error(what), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

/// A decoded message: its type name, the protocol version it carried, and the message itself.
struct Decoded {
  std::string type;
  uint32_t version = 0;
  std::unique_ptr<google::protobuf::Message> message;

  /// True when the sender speaks our protocol version.
  bool version_ok() const { return version == kProtocolVersion; }
  /// The message as T, or nullptr when it is another type.
  template <class T>
  const T* as() const {
    return type == T::descriptor()->full_name() ? static_cast<const T*>(message.get()) : nullptr;
  }
  template <class T>
  T* as_mutable() {
    return type == T::descriptor()->full_name() ? static_cast<T*>(message.get()) : nullptr;
  }
};

/// Serializes `message` (any wire message) without changing its version field.
net::Frames encode_raw(const google::protobuf::Message& message);

/// Stamps `version` into `message` and returns its two frames.
template <class M>
net::Frames encode(M message, uint32_t version = kProtocolVersion) {
  message.set_protocol_version(version);
  return encode_raw(message);
}

/// Parses two frames into a wire message. Throws DecodeError. A message of another protocol
/// version is returned (check version_ok()), so that the receiver can answer with a Refusal.
Decoded decode(const net::Frames& frames);

/// True when `descriptor` is a wire message: in package rayfarm.wire with field 1
/// "protocol_version" (uint32).
bool is_wire_message(const google::protobuf::Descriptor* descriptor);

/// The frames' type name for logs, made printable and cut short; "" when there is none.
std::string describe_frames(const net::Frames& frames);

/// Text from a peer (a name, a type frame) made safe for one log line: anything but printable
/// ASCII, and quotes and backslashes, become '?'; longer text is cut at `limit` and marked "...".
std::string printable(std::string_view text, size_t limit = 64);

}  // namespace rayfarm::protocol
