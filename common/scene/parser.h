#pragma once
// Reads any scene file into a validated Scene: the entry point of every format (JSON,
// docs/scene-format.md; glTF 2.0, docs/gltf.md; Mitsuba 3 XML, docs/mitsuba.md).
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "common/scene/gltf_loader.h"
#include "common/scene/gltf_scene.h"
#include "common/scene/scene.h"
#include "common/scene/scene_files.h"
#include "common/scene/texture_reader.h"

namespace rayfarm {

/// Loads, resolves (OBJ meshes, quads, triangles) and validates a scene file, decoding every
/// texture image (kept, or dropped once checked: `images`). A ".gltf" or ".glb" file is read as
/// glTF 2.0 (docs/gltf.md), through the camera `gltf` names; a JSON scene names its glTF file
/// itself. A ".xml" file is read as a Mitsuba 3 scene (docs/mitsuba.md), which may read files
/// anywhere under `root` (empty: its own folder). An animated JSON scene (common/scene/animation.h)
/// is read at `frame`, by default its first; asking a still scene for a frame, or an animated one
/// for a frame outside its range, is a SceneError. A scene without any light gets a warning
/// (kNoLightWarning). Throws SceneError (SceneRefused when `check` refuses it).
Scene load_scene(const std::filesystem::path& file, const SceneCheck& check = {},
                 SceneImages images = SceneImages::kKeep, const GltfOptions& gltf = {},
                 const std::filesystem::path& root = {},
                 std::optional<int64_t> frame = std::nullopt);

/// The scene of load_scene() posed `frame_offset` frames after `frame` (a fraction of a frame:
/// the poses within an open shutter, common/scene/motion.h), its images not read.
Scene load_scene_pose(const std::filesystem::path& file, const GltfOptions& gltf,
                      const std::filesystem::path& root, std::optional<int64_t> frame,
                      double frame_offset);

/// The frames of the scene in `file` (its "animation" block, or a glTF file's animations),
/// reading no more than that needs; nullopt for a still scene. Throws SceneError as load_scene()
/// does.
std::optional<FrameRange> load_scene_animation(const std::filesystem::path& file);

}  // namespace rayfarm
