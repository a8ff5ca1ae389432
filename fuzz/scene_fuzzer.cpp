// libFuzzer target: a scene file (JSON). The scene may refer to "m.obj" (with "m.mtl"), which
// exist beside it. load_scene() must load it or throw SceneError, nothing else, and what it
// loads must satisfy check_scene().
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/scene/parser.h"
#include "fuzz_support.h"
#include "scene_checks.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rayfarm;
  static const bool ready = [] {
    fuzz::write_scratch("m.obj", "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n");
    fuzz::write_scratch("m.mtl", "newmtl a\nKd 0.5 0.5 0.5\nKe 1 1 1\n");
    return true;
  }();
  (void)ready;
  const auto file = fuzz::write_scratch("scene.json", std::string(reinterpret_cast<const char*>(data), size));
  try {
    fuzz::check_scene(load_scene(file));
  } catch (const SceneError&) {
  }
  return 0;
}
