#pragma once
// A list of scene files, one still scene per frame: a scene name whose file name holds a frame
// pattern ("shots/frame_####.json", "frame_%04d.json"; common/scene/frames.h), as the CLI reads
// it and the master checks and hands out its frames.
#include <cstdint>
#include <filesystem>

#include "common/scene/frames.h"

namespace rayfarm {

/// Whether `scene` names a list of scene files (its file name holds a frame pattern).
inline bool is_scene_list(const std::filesystem::path& scene) {
  return has_frame_pattern(scene.filename().string());
}

/// The scene file of `frame` in the list `pattern`. Throws std::invalid_argument on a malformed
/// '%'.
inline std::filesystem::path frame_scene_file(const std::filesystem::path& pattern, int64_t frame) {
  return pattern.parent_path() / substitute_frame(pattern.filename().string(), frame);
}

}  // namespace rayfarm
