#pragma once
// --frames A-B[:STEP], as `rayfarm render` and `rayfarm submit` both check it before any work:
// the list itself, then against the scene's animation (docs/scene-format.md, "Animation").
#include <optional>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "common/scene/frames.h"
#include "common/scene/parser.h"

namespace rayfarm::cli {

/// The frames `text` names in the animation of `scene`; throws std::invalid_argument naming the
/// option when the list is malformed or reversed, the scene is a still, or a frame lies beyond its
/// animation, and when `reference` is set (one reference image cannot measure a sequence).
inline FrameList check_frames_option(const std::string& text, const std::string& scene,
                                     bool reference) {
  std::string why;
  const auto frames = parse_frame_list(text, &why);
  if (!frames) throw std::invalid_argument("--frames: " + why);
  if (reference) {
    throw std::invalid_argument(
        "--reference is one image; it cannot measure a sequence (render a frame with --frame N "
        "and its reference)");
  }
  const std::optional<FrameRange> animation = load_scene_animation(scene);
  if (!animation) {
    throw std::invalid_argument("--frames " + text + ": " + scene +
                                " is a still scene (it has no animation)");
  }
  if (!animation->contains(frames->first) || !animation->contains(frames->last)) {
    throw std::invalid_argument(
        fmt::format("--frames {}: beyond the scene's animation, frames {}-{}", text,
                    animation->first, animation->last));
  }
  return *frames;
}

}  // namespace rayfarm::cli
