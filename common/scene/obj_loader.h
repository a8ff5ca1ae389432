#pragma once
// Wavefront OBJ meshes and their MTL materials, read into rayfarm's data model
// (docs/scene-format.md, "Meshes").
#include <filesystem>
#include <string>
#include <vector>

#include "common/scene/scene_files.h"

namespace rayfarm {

/// Reads `relative` (relative to `scene_dir`, already resolved) and the MTL files it names.
/// Throws SceneError "FILE:LINE: ..." for any problem in the files.
/// `materials` false: mtllib and usemtl lines are ignored (Mitsuba's reading); every face gets
/// the material "<file>:default".
MeshFile load_obj(const std::filesystem::path& scene_dir, const std::filesystem::path& relative,
                  bool materials = true);

}  // namespace rayfarm
