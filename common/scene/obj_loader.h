#pragma once
// Wavefront OBJ meshes and their MTL materials, read into rayfarm's data model
// (docs/scene-format.md, "Meshes"). Also what the JSON parser shares with it: the rule that keeps
// every file a scene refers to inside the scene's folder, and bounded file reading.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/scene/scene.h"

namespace rayfarm {

/// Largest OBJ file read, in bytes.
inline constexpr std::uintmax_t kMaxObjFileBytes = std::uintmax_t{1} << 30;
/// Largest MTL file read, in bytes.
inline constexpr std::uintmax_t kMaxMtlFileBytes = std::uintmax_t{16} << 20;

/// Resolves `reference` (as written in a file) against `base_dir`, both relative to the scene
/// folder. Returns the lexically normal path relative to the scene folder, or nullopt with `why`
/// set when the reference is empty, absolute, or leaves the scene folder.
std::optional<std::filesystem::path> resolve_scene_path(const std::filesystem::path& base_dir,
                                                        const std::string& reference,
                                                        std::string* why);

/// Reads a whole text file of at most `max_bytes`; SceneError "DISPLAY: ..." when that fails.
std::string read_text_file(const std::filesystem::path& file, std::uintmax_t max_bytes,
                           const std::string& display);

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
