#pragma once
// Reads a JSON scene file (docs/scene-format.md) into a validated Scene.
#include <filesystem>
#include <stdexcept>
#include <string>

#include "common/scene/scene.h"

namespace rayfarm {

/// A user's error in a scene: the message names the file and the JSON path or line,
/// e.g. "scenes/box.json: /materials/red/albedo/1: expected a number, got \"x\"".
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Loads, resolves (OBJ meshes, quads, triangles) and validates a scene file. Throws SceneError.
Scene load_scene(const std::filesystem::path& file);

}  // namespace rayfarm
