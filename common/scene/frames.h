#pragma once
// Frames: the range an animated scene defines (common/scene/animation.h), and the frame lists
// that the command line and jobs take ("1-240:2").
#include <cstdint>
#include <optional>
#include <string>

namespace rayfarm {

/// The frames of an animated scene: first to last, both included, played at fps frames a second.
struct FrameRange {
  int64_t first = 1;
  int64_t last = 1;
  double fps = 24.0;
  int64_t count() const { return last - first + 1; }
  bool contains(int64_t frame) const { return frame >= first && frame <= last; }
};

/// Frame numbers (of animation blocks and of --frame options) are within +-kMaxFrameNumber.
inline constexpr int64_t kMaxFrameNumber = 1'000'000'000;

/// Frames a second of a glTF file's animation: its frame 1 is time 0.
inline constexpr double kGltfFps = 24.0;

/// A frame range written "A-B" or "A-B:STEP" (or a single frame "A"), as the command line and
/// jobs take it.
struct FrameList {
  int64_t first = 1;
  int64_t last = 1;
  int64_t step = 1;
  int64_t count() const { return (last - first) / step + 1; }
  int64_t at(int64_t index) const { return first + index * step; }
};

/// Parses "A", "A-B" or "A-B:STEP" (A <= B, STEP >= 1, |A|, |B| <= kMaxFrameNumber; negative
/// frames are written "-5--1"); nullopt with `why` set when malformed.
std::optional<FrameList> parse_frame_list(const std::string& text, std::string* why);
/// "A-B:STEP", "A-B" when the step is 1, "A" for one frame.
std::string frame_list_name(const FrameList& frames);

/// Whether a file name holds a frame number pattern: a run of '#' or a '%' (a printf "%d" or
/// "%0Nd"). Output names take the frame number so; a scene name so is a list of scene files, one
/// per frame ("shots/frame_####.json").
bool has_frame_pattern(const std::string& file_name);
/// `file_name` with its pattern replaced by `frame`, padded with zeros to the pattern's width
/// ("shot.####.exr" -> "shot.0012.exr", "frame_%04d.json" -> "frame_0012.json"); unchanged
/// without one. Throws std::invalid_argument when a '%' is not "%d" or "%0Nd".
std::string substitute_frame(const std::string& file_name, int64_t frame);

}  // namespace rayfarm
