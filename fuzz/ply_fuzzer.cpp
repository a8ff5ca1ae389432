// libFuzzer target: a PLY file, ASCII or binary. Two fixed scenes refer to it, one as written and
// one with a shape material and a mirroring transform; load_scene() must load each or throw
// SceneError, and what it loads must satisfy check_scene().
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/scene/parser.h"
#include "fuzz_support.h"
#include "scene_checks.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rayfarm;
  static const std::string kHead =
      R"({"camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40},
          "film": {"width": 4, "height": 4},
          "materials": {"m": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
          "shapes": [)";
  static const std::filesystem::path plain =
      fuzz::write_scratch("ply.json", kHead + R"({"type": "mesh", "file": "f.ply"}]})");
  static const std::filesystem::path moved = fuzz::write_scratch(
      "ply-moved.json", kHead + R"({"type": "mesh", "file": "f.ply", "material": "m",
                                    "transform": [{"scale": [-1, 2, 1]}, {"translate": [1, 0, 0]}]}]})");
  fuzz::write_scratch("f.ply", std::string(reinterpret_cast<const char*>(data), size));
  for (const auto& scene : {plain, moved}) {
    try {
      fuzz::check_scene(load_scene(scene));
    } catch (const SceneError&) {
    }
  }
  return 0;
}
