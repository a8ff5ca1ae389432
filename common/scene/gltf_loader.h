#pragma once
// glTF 2.0 scenes (.gltf with its buffers and images, or one .glb), read with tinygltf and checked
// by us: every accessor, index, node and image is validated before it is used, so a malformed
// file is a SceneError naming the file and the glTF object, never a crash. docs/gltf.md.
#include <filesystem>
#include <string>

#include "common/scene/scene.h"
#include "common/scene/texture_reader.h"

namespace rayfarm {

/// What the caller chooses about a glTF file.
struct GltfOptions {
  /// The camera to render through: a camera's or its node's name. Empty: the first camera met in
  /// the scene's node hierarchy (depth first, in the order the nodes list their children).
  std::string camera;
};

/// What load_gltf() found besides what it added to the scene.
struct GltfResult {
  bool has_camera = false;  ///< a camera was found and set in Scene::camera
  /// The camera's aspect ratio (width / height) when the file states one, else 0.
  double aspect = 0.0;
};

/// Adds the meshes, materials, textures and lights of the glTF file `relative` (to `folder`, the
/// scene's folder) to `scene`, and its camera. Materials keep their glTF names (unnamed ones are
/// called "gltf:material[N]"); `scene.referenced` gets the file and every buffer and image file
/// it names. Throws SceneError.
GltfResult load_gltf(const std::filesystem::path& folder, const std::filesystem::path& relative,
                     const GltfOptions& options, SceneImages images, Scene& scene);

/// True when `file`'s extension says glTF (".gltf" or ".glb", any case).
bool is_gltf_path(const std::filesystem::path& file);

}  // namespace rayfarm
