// libFuzzer target: a glTF 2.0 file, binary (.glb) when the input starts with the "glTF" magic,
// else text (.gltf, whose buffers and images are data URIs or the file "f.bin", which stays
// empty). load_scene() must load it or throw SceneError, and what it loads must satisfy
// check_scene().
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/scene/parser.h"
#include "fuzz_support.h"
#include "scene_checks.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rayfarm;
  static const std::filesystem::path bin = fuzz::write_scratch("f.bin", "");
  const std::string input(reinterpret_cast<const char*>(data), size);
  const bool binary = input.rfind("glTF", 0) == 0;
  const std::filesystem::path file = fuzz::write_scratch(binary ? "f.glb" : "f.gltf", input);
  try {
    fuzz::check_scene(load_scene(file, {}, SceneImages::kCheckOnly));
  } catch (const SceneError&) {
  }
  (void)bin;
  return 0;
}
