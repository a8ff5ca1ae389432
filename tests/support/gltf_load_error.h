#pragma once
// The SceneError that loading a built glTF file gives, for tests of malformed files.
#include <string>

#include "common/scene/parser.h"
#include "tests/support/gltf_builder.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::testing {

/// The message of the SceneError that loading `b` as a .glb throws; "" when it loads.
inline std::string glb_error(const GltfBuilder& b) {
  TempDir dir;
  try {
    load_scene(dir.write("bad.glb", b.glb()));
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

}  // namespace rayfarm::testing
