#pragma once
// glTF 2.0 scenes (.gltf with its buffers and images, or one .glb), read with tinygltf and checked
// by us: every accessor, index, node and image is validated before it is used, so a malformed
// file is a SceneError naming the file and the glTF object, never a crash. docs/gltf.md.
#include <filesystem>
#include <string>

#include "common/scene/gltf_options.h"
#include "common/scene/scene.h"
#include "common/scene/texture_reader.h"

namespace rayfarm {

/// Adds the meshes, materials, textures and lights of the glTF file `relative` (to `folder`, the
/// scene's folder) to `scene`, and its camera. Materials keep their glTF names (unnamed ones are
/// called "gltf:material[N]"); `scene.referenced` gets the file and every buffer and image file
/// it names. Throws SceneError.
GltfResult load_gltf(const std::filesystem::path& folder, const std::filesystem::path& relative,
                     const GltfOptions& options, SceneImages images, Scene& scene);

/// True when `file`'s extension says glTF (".gltf" or ".glb", any case).
bool is_gltf_path(const std::filesystem::path& file);

}  // namespace rayfarm
