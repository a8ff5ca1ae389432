#pragma once
// Conversions between rayfarm's types and the wire messages. Conversions from the wire check what
// they read and throw ProtocolError (a well-formed message with impossible content) naming it.
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "common/bundle/bundle.h"
#include "common/image/film.h"
#include "common/scene/scene.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::protocol {

namespace wire = ::rayfarm::wire;

/// A decoded message whose content is invalid (sizes, ranges, enums); what() names the field.
class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Most bytes one fixed-point value takes on the wire (pack_fixed): 128 bits, 7 a byte.
inline constexpr size_t kMaxFixedWireBytes = 19;

wire::Integrator integrator_to_wire(IntegratorType type);
/// Throws ProtocolError on INTEGRATOR_UNSPECIFIED or an unknown value.
IntegratorType integrator_from_wire(wire::Integrator value);
wire::Sampler sampler_to_wire(SamplerType type);
/// Throws ProtocolError on SAMPLER_UNSPECIFIED or an unknown value.
SamplerType sampler_from_wire(wire::Sampler value);
wire::Roulette roulette_to_wire(RouletteType type);
/// Throws ProtocolError on ROULETTE_UNSPECIFIED or an unknown value.
RouletteType roulette_from_wire(wire::Roulette value);

wire::RenderSettings settings_to_wire(const RenderSettings& settings);
/// Whether two scenes' render settings are the same (every field).
bool same_settings(const RenderSettings& a, const RenderSettings& b);
/// Throws ProtocolError on an unknown integrator or zero spp.
RenderSettings settings_from_wire(const wire::RenderSettings& settings);

/// A frame list on the wire (step 0: none).
wire::FrameList frames_to_wire(const FrameList& frames);
/// nullopt for step 0 (a single job); throws ProtocolError naming the fault of a list that is
/// reversed, has a negative step or frames beyond +-kMaxFrameNumber.
std::optional<FrameList> frames_from_wire(const wire::FrameList& frames);
/// How many frames a list on the wire holds (1 for none, the count of a malformed one's first and
/// last as they are, never 0): what a submission adds to the master's queue.
uint64_t frame_count(const wire::FrameList& frames);

wire::Rect rect_to_wire(const TileRect& rect);
/// Throws ProtocolError on an empty rectangle or one wider or taller than 65536 pixels.
TileRect rect_from_wire(const wire::Rect& rect);

/// Packs fixed-point values for the wire, each as a variable-length integer: the value's sign
/// folded into its lowest bit (zigzag: 0, -1, 1, -2 ... become 0, 1, 2, 3 ...), then 7 bits a
/// byte, least significant first, the top bit of each byte set while more follow (LEB128). A sum
/// of a few hundred samples of moderate value takes 7 or 8 bytes instead of 16; any value at most
/// kMaxFixedWireBytes. Exact: unpack_fixed gives back the same bits.
std::string pack_fixed(const std::vector<Fixed>& values);
/// Unpacks exactly `count` values that take all of `bytes`; throws ProtocolError naming the
/// fault (too few or too many bytes, a value cut short or wider than 128 bits). Allocates only
/// once `bytes` could hold `count` values (one byte each at least): up to 16 bytes of values for
/// each byte read, so a caller that takes `count` from a peer checks it first (the master checks
/// a result's tile against its unit before decoding).
std::vector<Fixed> unpack_fixed(std::string_view bytes, size_t count);

/// The wire form of a rendered unit.
wire::UnitResult result_to_wire(const std::string& job_id, uint64_t unit_id,
                                const TileResult& result, double render_seconds);
/// A rendered unit read back; throws ProtocolError when the rectangle, sample range or sum sizes
/// are inconsistent. The result is well_formed().
TileResult result_from_wire(const wire::UnitResult& result);

void bundle_to_wire(const Bundle& bundle, wire::Bundle* out);
/// Throws BundleError on a bad or repeated path.
Bundle bundle_from_wire(const wire::Bundle& bundle);

/// Name of a job state for people ("queued", "running", "done", "failed", "cancelled").
const char* job_state_name(wire::JobState state);

}  // namespace rayfarm::protocol
