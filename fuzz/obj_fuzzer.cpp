// libFuzzer target: an OBJ file and its MTL file, separated by the first NUL byte of the input
// (OBJ before, MTL after). A fixed scene refers to the OBJ; load_scene() must load it or throw
// SceneError, and what it loads must satisfy check_scene().
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/scene/parser.h"
#include "fuzz_support.h"
#include "scene_checks.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rayfarm;
  static const std::filesystem::path scene = fuzz::write_scratch(
      "obj.json",
      R"({"camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40},
          "film": {"width": 4, "height": 4},
          "shapes": [{"type": "mesh", "file": "f.obj"}]})");
  const std::string input(reinterpret_cast<const char*>(data), size);
  const size_t nul = input.find('\0');
  fuzz::write_scratch("f.obj", input.substr(0, nul));
  fuzz::write_scratch("f.mtl", nul == std::string::npos ? std::string() : input.substr(nul + 1));
  try {
    fuzz::check_scene(load_scene(scene));
  } catch (const SceneError&) {
  }
  return 0;
}
