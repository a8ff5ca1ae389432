#pragma once
// What every scene format reader shares: the error it throws, what a mesh file reader returns,
// the rule that keeps every file a scene refers to inside the scene's folder, and bounded file
// reading.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/scene/scene.h"

namespace rayfarm {

/// A user's error in a scene: the message names the file and the JSON path or line,
/// e.g. "scenes/box.json: /materials/red/albedo/1: expected a number, got \"x\"".
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A caller's limits on a scene's film and render settings (the master's, for a job): called
/// once load_scene() has read "film" and "render", before the camera, the materials and the
/// shapes (so before any mesh is loaded); returns the refusal, or nothing when the scene may load.
using SceneCheck =
    std::function<std::optional<std::string>(const FilmSize& film, const RenderSettings& render)>;

/// A scene refused by the caller's SceneCheck; what() is the check's message alone.
class SceneRefused : public SceneError {
 public:
  using SceneError::SceneError;
};

/// A loaded mesh file (OBJ or PLY): one mesh whose material indices point into `materials`.
struct MeshFile {
  TriangleMesh mesh;                         ///< fan-triangulated faces, zero-area ones dropped
  std::vector<Material> materials;           ///< named "<file>:<name>" (MTL ones, or "default")
  std::vector<std::filesystem::path> files;  ///< files read, relative to the scene
  std::vector<std::string> warnings;         ///< problems that were tolerated, with their place
  /// OBJ: the first triangle of each object ("o") or group ("g") after the first, ascending;
  /// empty when the file holds one (split_objects() makes each a mesh of its own).
  std::vector<uint32_t> object_starts;
  /// With object_starts: each object's name (its o or g line's, quoted and shortened as messages
  /// show names), "" where it has none.
  std::vector<std::string> object_names;
};

/// Most objects of an OBJ file that become meshes of their own; a file with more stays one mesh
/// (MeshFile::object_starts is then empty).
inline constexpr size_t kMaxMeshObjects = 4096;
/// Most meshes that the objects of a scene's OBJ files may become in all; the files read after
/// the budget is spent stay one mesh each. Each mesh is an Embree geometry on every worker: the
/// budget keeps a small scene naming a file of thousands of one-triangle objects many times from
/// making the master and the workers hold a mesh per triangle.
inline constexpr size_t kMaxSplitMeshes = 65536;

/// The meshes of `mesh`'s objects, `starts` their first triangles (MeshFile::object_starts): each
/// keeps its triangles in order and the vertices they use (with their normals, texture
/// coordinates and tangents), its origin `<origin> (object NAME)` with its (quoted) name from
/// `names`, or `<origin> (object N)` (N from 1) without one. The mesh itself when `starts` is empty or
/// holds kMaxMeshObjects or more. Apart, each object gets a tree of its own in the BVH where
/// objects keep to their own space (renderer/embree/build_choice.h).
std::vector<TriangleMesh> split_objects(TriangleMesh&& mesh, const std::vector<uint32_t>& starts,
                                        const std::vector<std::string>& names = {});
/// split_objects() of a file's mesh by its objects.
inline std::vector<TriangleMesh> split_objects(MeshFile&& file) {
  return split_objects(std::move(file.mesh), file.object_starts, file.object_names);
}

/// Resolves `reference` (as written in a file) against `base_dir`, both relative to the scene
/// folder. Returns the lexically normal path relative to the scene folder, or nullopt with `why`
/// set when the reference is empty, absolute, or leaves the scene folder.
std::optional<std::filesystem::path> resolve_scene_path(const std::filesystem::path& base_dir,
                                                        const std::string& reference,
                                                        std::string* why);

/// Reads a whole text file of at most `max_bytes`; SceneError "DISPLAY: ..." when that fails.
std::string read_text_file(const std::filesystem::path& file, std::uintmax_t max_bytes,
                           const std::string& display);

}  // namespace rayfarm
