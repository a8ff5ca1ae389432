#pragma once
// Keyframed animation in JSON scenes (docs/scene-format.md, "Animation"). A scene with an
// "animation" block is a sequence of frames; any number or array of numbers of its camera,
// shapes, groups, materials, textures, lights or background may then be written as keyframes
// instead of a value:
//
//   "eye": {"keyframes": [[1, [0, 1, 5]], [48, [2, 1, 5]]], "interpolation": "smooth"}
//
// Loading the scene at a frame replaces every keyframed value by its value at that frame, before
// the scene is read as a still one: the rest of the reader (and its checks) sees plain values.
#include <optional>

#include "common/scene/frames.h"
#include "common/scene/json_reader.h"

namespace rayfarm {

namespace scene_json {

/// Reads the top level's "animation" block ({"frames": [FIRST, LAST], "fps": F}); nullopt when
/// the scene has none.
std::optional<FrameRange> read_animation(const Node& root);

/// `root` with every keyframed value replaced by its value at `frame`; nullopt when nothing is
/// keyframed (`root` is read as it is). Keyframes are refused (naming their place) under "film",
/// "render", "format", "gltf" and "animation", and anywhere when `animation` is nullopt (a still
/// scene). Throws SceneError naming the place of a malformed keyframe list.
std::optional<Json> resolve_keyframes(const Node& root, const std::optional<FrameRange>& animation,
                                      double frame);

}  // namespace scene_json

/// Throws SceneError naming `file` when `frame` is given and the scene is a still (`animation`
/// nullopt) or the frame is outside its animation.
void check_frame(const std::string& file, const std::optional<FrameRange>& animation,
                 std::optional<int64_t> frame);

}  // namespace rayfarm
