#pragma once
// Wavefront OBJ meshes and their MTL materials, read into rayfarm's data model
// (docs/scene-format.md, "Meshes").
#include <filesystem>
#include <string>
#include <vector>

#include "common/scene/scene.h"

namespace rayfarm {

/// A loaded OBJ file: one mesh whose material indices point into `materials`.
struct ObjMesh {
  TriangleMesh mesh;                         ///< fan-triangulated faces, zero-area ones dropped
  std::vector<Material> materials;           ///< from the MTL files, named "<obj>:<mtl name>"
  std::vector<std::filesystem::path> files;  ///< OBJ and MTL files read, relative to the scene
  std::vector<std::string> warnings;         ///< "FILE:LINE: ..." problems that were tolerated
};

/// Reads `relative` (relative to `scene_dir`, already resolved) and the MTL files it names.
/// Throws SceneError "FILE:LINE: ..." for any problem in the files.
ObjMesh load_obj(const std::filesystem::path& scene_dir, const std::filesystem::path& relative);

}  // namespace rayfarm
