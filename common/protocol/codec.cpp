#include "common/protocol/codec.h"

#include <google/protobuf/descriptor.h>

#include "common/util/text.h"

namespace rayfarm::protocol {
namespace gp = google::protobuf;

namespace {

const gp::FieldDescriptor* version_field(const gp::Descriptor* d) {
  const gp::FieldDescriptor* f = d->FindFieldByNumber(1);
  if (f == nullptr || f->name() != "protocol_version" ||
      f->cpp_type() != gp::FieldDescriptor::CPPTYPE_UINT32 || f->is_repeated()) {
    return nullptr;
  }
  return f;
}

}  // namespace

bool is_wire_message(const gp::Descriptor* descriptor) {
  return descriptor != nullptr && descriptor->file()->package() == "rayfarm.wire" &&
         version_field(descriptor) != nullptr;
}

net::Frames encode_raw(const gp::Message& message) {
  net::Frames frames(2);
  frames[0] = message.GetDescriptor()->full_name();
  if (!message.SerializeToString(&frames[1])) {
    // Only a message over 2 GiB fails to serialize; the codec's callers never build one.
    throw std::length_error("cannot serialize " + frames[0]);
  }
  return frames;
}

Decoded decode(const net::Frames& frames) {
  // Referencing a generated type keeps rayfarm.proto registered in the generated pool.
  static const gp::Descriptor* const kAnchor = wire::Hello::descriptor();
  (void)kAnchor;

  if (frames.size() != 2) {
    throw DecodeError(DecodeError::Kind::kFrameCount,
                      "expected 2 frames (type, body), got " + std::to_string(frames.size()));
  }
  const std::string& type = frames[0];
  const std::string& body = frames[1];
  if (type.size() > kMaxTypeBytes) {
    throw DecodeError(DecodeError::Kind::kTooLarge, "type frame of " + std::to_string(type.size()) +
                                                        " bytes (limit " +
                                                        std::to_string(kMaxTypeBytes) + ")");
  }
  if (body.size() > kMaxBodyBytes) {
    throw DecodeError(DecodeError::Kind::kTooLarge,
                      "body of " + std::to_string(body.size()) + " bytes for '" +
                          printable(type, 48) + "' (limit " + std::to_string(kMaxBodyBytes) + ")");
  }
  const gp::Descriptor* descriptor =
      gp::DescriptorPool::generated_pool()->FindMessageTypeByName(type);
  if (!is_wire_message(descriptor)) {
    throw DecodeError(DecodeError::Kind::kUnknownType,
                      "unknown message type '" + printable(type, 48) + "'");
  }
  const gp::Message* prototype = gp::MessageFactory::generated_factory()->GetPrototype(descriptor);
  Decoded out;
  out.type = type;
  out.message.reset(prototype->New());
  if (!out.message->ParseFromString(body)) {
    throw DecodeError(
        DecodeError::Kind::kMalformedBody,
        "malformed body for '" + type + "' (" + std::to_string(body.size()) + " bytes)");
  }
  out.version = out.message->GetReflection()->GetUInt32(*out.message, version_field(descriptor));
  return out;
}

std::string printable(std::string_view text, size_t limit) {
  return rayfarm::printable(text, limit, Quotes::kHide);
}

std::string describe_frames(const net::Frames& frames) {
  if (frames.empty()) return "";
  return printable(frames[0], 48);
}

}  // namespace rayfarm::protocol
