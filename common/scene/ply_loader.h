#pragma once
// Stanford PLY meshes (ASCII and binary, either byte order), read into rayfarm's data model
// (docs/scene-format.md, "PLY meshes").
#include <filesystem>

#include "common/scene/scene_files.h"

namespace rayfarm {

/// Whether a mesh file is read as PLY: its extension is ".ply" in any case (others are OBJ).
bool is_ply_file(const std::filesystem::path& file);

/// Reads the PLY file `relative` (relative to `scene_dir`, already resolved): its vertex positions,
/// normals and texture coordinates, and its faces fan-triangulated. Every face gets the material
/// "<file>:default". Throws SceneError naming the file and the place: "FILE:LINE: ..." for the
/// header and an ASCII body, "FILE: face 12 (byte 3456): ..." for a binary body.
MeshFile load_ply(const std::filesystem::path& scene_dir, const std::filesystem::path& relative);

}  // namespace rayfarm
