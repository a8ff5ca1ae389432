#pragma once
// A glTF 2.0 file loaded as a whole scene (`rayfarm render model.glb`): its film, a default camera
// when it has none, and its animation's frames (docs/gltf.md).
#include <cstdint>
#include <filesystem>
#include <optional>

#include "common/scene/gltf_options.h"
#include "common/scene/scene.h"
#include "common/scene/scene_files.h"
#include "common/scene/texture_reader.h"

namespace rayfarm {

/// Film of a glTF file rendered directly: 540 rows, as wide as its camera's aspect ratio says
/// (16:9 when it says none).
FilmSize default_gltf_film(double aspect);

/// The end of the warning a scene without a camera gets (default_view()): the default camera is
/// placed from the meshes' bounds at each frame (and kept still within a shutter).
inline constexpr const char* kDefaultViewWarning =
    "; a default one frames the meshes from the front (+z), 30 degrees to the right (+x) and 25 "
    "degrees above (+y)";

/// A camera for a scene that has none (a glTF file without one, or a JSON scene naming such a
/// file without a "camera"): the default perspective camera looking at the middle of the
/// bounds of its meshes and spheres from kDefaultViewWarning's direction, far enough that the
/// bounding sphere fits the view.
Camera default_view(const Scene& scene);

/// The glTF file `file` as a scene, at `frame` of its animation (frame 1, time 0, when nullopt;
/// kGltfFps frames a second). Throws SceneError (SceneRefused when `check` refuses its film).
Scene load_gltf_scene(const std::filesystem::path& file, const SceneCheck& check,
                      SceneImages images, GltfOptions options, std::optional<int64_t> frame,
                      double frame_offset = 0.0);

}  // namespace rayfarm
