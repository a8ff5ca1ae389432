#pragma once
// The wire protocol's version. Every message carries it (field 1, stamped by the codec); a peer
// that speaks another version is refused with a message naming both. Bump it on any change to
// proto/rayfarm.proto that an older peer would misread.
#include <cstdint>

namespace rayfarm::protocol {

// 2: WorkUnit carries the job's film (a job may override the scene's), which a version-1 worker
// would ignore, rendering the wrong image.
// 3: Error (and a refused SubmitReply) carries a code, which peers act on instead of the message
// text; a version-2 peer would act on text that a version-3 master no longer promises.
// 4: RenderSettings carries the sampler and the roulette rule, which a version-3 worker would
// ignore, rendering other samples than the job's (the image would no longer be the local one).
// 5: SubmitJob carries a priority and may ask to be held paused, which a version-4 master would
// ignore, starting a job its submitter asked to hold; ChangeJob pauses, resumes and reprioritises.
// UnitResult's sums are variable-length integers (pack_fixed) instead of 16 bytes each.
// 6: WorkUnit carries the frame of an animated scene, which a version-5 worker would ignore,
// rendering the first frame instead.
// 7: RenderSettings carries the shutter of motion blur, which a version-6 worker would ignore,
// rendering the frame unblurred (the image would no longer be the local one).
// 8: RenderSettings may carry the roulette rule ROULETTE_ROOT (the default), which a version-7
// worker would refuse unit by unit.
inline constexpr uint32_t kProtocolVersion = 8;

/// Software version of this build, sent in Hello and Welcome for the logs.
inline constexpr const char* kBuildVersion = "rayfarm 0.2.0";

}  // namespace rayfarm::protocol
