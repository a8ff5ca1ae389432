#pragma once
// What a caller chooses about a glTF file, and what reading one found besides the scene.
#include <optional>
#include <set>
#include <string>

namespace rayfarm {

/// What the caller chooses about a glTF file.
struct GltfOptions {
  /// The camera to render through: a camera's or its node's name. Empty: the first camera met in
  /// the scene's node hierarchy (depth first, in the order the nodes list their children).
  std::string camera;
  /// Names of the file's materials that the JSON scene replaces: their meshes keep texture
  /// coordinates and tangents even where the file's own material would not read them.
  std::set<std::string> replaced_materials;
  /// The time in seconds at which the file's animations pose its nodes; nullopt: the nodes as
  /// written.
  std::optional<double> time;
  /// Light for a file rendered directly (`--environment`): "uniform" (a constant radiance of 1
  /// from every direction), an image file relative to the glTF file's folder (an environment
  /// map, as a JSON scene's "environment" light), or empty: the file's own lights alone.
  std::string environment;
};

/// What load_gltf() found besides what it added to the scene.
struct GltfResult {
  bool has_camera = false;  ///< a camera was found and set in Scene::camera
  /// The camera's aspect ratio (width / height) when the file states one, else 0.
  double aspect = 0.0;
  /// The time of the file's last animation key in seconds; 0 when it has no animation.
  double duration = 0.0;
};

}  // namespace rayfarm
