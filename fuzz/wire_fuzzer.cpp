// libFuzzer target: one message as the master or a worker receives it. The input is the type
// frame, a newline, and the body frame ("rayfarm.wire.UnitResult\n<protobuf bytes>"); an input
// without a newline is sent as a single frame. decode() must return a message or throw
// DecodeError; the conversions that turn wire messages into rayfarm's types must return a
// consistent value or throw ProtocolError / BundleError; nothing else may escape.
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/bundle/bundle.h"
#include "common/image/film.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "fuzz_support.h"

namespace {

using namespace rayfarm;
namespace wire = rayfarm::wire;

/// What the receivers do with each message that carries content to convert.
void convert(const protocol::Decoded& d) {
  if (const auto* result = d.as<wire::UnitResult>()) {
    const TileResult r = protocol::result_from_wire(*result);
    fuzz::require(r.well_formed(), "result_from_wire returned a malformed result");
    // The master merges it into a film that fits it, as the merger does after Film::fits().
    if (uint64_t{r.rect.x1} * r.rect.y1 <= (1u << 20)) {
      Film film(r.rect.x1, r.rect.y1);
      fuzz::require(film.fits(r), "a well-formed result does not fit the film it spans");
      film.add(r);
      (void)film.mean_rgb();
    }
  } else if (const auto* unit = d.as<wire::WorkUnit>()) {
    const TileRect rect = protocol::rect_from_wire(unit->tile());
    fuzz::require(rect.width() > 0 && rect.height() > 0, "empty tile accepted");
    const RenderSettings s = protocol::settings_from_wire(unit->settings());
    fuzz::require(s.spp > 0, "zero spp accepted");
    (void)is_bundle_hash(unit->bundle_hash());
  } else if (const auto* reply = d.as<wire::BundleReply>()) {
    const Bundle b = protocol::bundle_from_wire(reply->bundle());
    for (const BundleFile& f : b.files) check_bundle_path(f.path);
    (void)bundle_hash(b);
  } else if (const auto* submit = d.as<wire::SubmitJob>()) {
    const Bundle b = protocol::bundle_from_wire(submit->bundle());
    (void)bundle_hash(b);
    if (submit->overrides().integrator() != wire::INTEGRATOR_UNSPECIFIED) {
      (void)protocol::integrator_from_wire(submit->overrides().integrator());
    }
  } else if (const auto* status = d.as<wire::JobStatus>()) {
    (void)protocol::job_state_name(status->state());
    (void)protocol::settings_from_wire(status->settings());
  } else if (const auto* list = d.as<wire::JobList>()) {
    for (const auto& job : list->jobs()) (void)protocol::job_state_name(job.state());
  } else if (const auto* cancel = d.as<wire::CancelReply>()) {
    (void)protocol::job_state_name(cancel->state());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  net::Frames frames;
  const size_t newline = input.find('\n');
  if (newline == std::string::npos) {
    frames.push_back(input);
  } else {
    frames.push_back(input.substr(0, newline));
    frames.push_back(input.substr(newline + 1));
  }
  (void)protocol::describe_frames(frames);
  protocol::Decoded decoded;
  try {
    decoded = protocol::decode(frames);
  } catch (const protocol::DecodeError& e) {
    (void)protocol::printable(e.what());
    return 0;
  }
  fuzz::require(decoded.message != nullptr, "decode returned no message");
  fuzz::require(protocol::is_wire_message(decoded.message->GetDescriptor()), "not a wire message");
  // What was decoded encodes and decodes again to the same bytes.
  const net::Frames again = protocol::encode_raw(*decoded.message);
  const protocol::Decoded second = protocol::decode(again);
  fuzz::require(second.message->SerializeAsString() == again[1], "re-encoding is not stable");
  try {
    convert(decoded);
  } catch (const protocol::ProtocolError&) {
  } catch (const BundleError&) {
  }
  return 0;
}
