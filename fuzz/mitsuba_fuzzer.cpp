// libFuzzer target: a Mitsuba 3 XML scene. Beside it lie a small OBJ ("m.obj"), a second XML file
// ("part.xml") that it may include, and an empty "e.png"; load_scene() must load the scene or
// throw SceneError, and what it loads must satisfy check_scene().
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/scene/parser.h"
#include "fuzz_support.h"
#include "scene_checks.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rayfarm;
  static const std::filesystem::path mesh = fuzz::write_scratch(
      "m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n");
  static const std::filesystem::path part =
      fuzz::write_scratch("part.xml", "<scene version=\"3.0.0\"><shape type=\"sphere\"/></scene>");
  static const std::filesystem::path image = fuzz::write_scratch("e.png", "");
  const std::string input(reinterpret_cast<const char*>(data), size);
  const std::filesystem::path file = fuzz::write_scratch("f.xml", input);
  try {
    fuzz::check_scene(load_scene(file, {}, SceneImages::kCheckOnly));
  } catch (const SceneError&) {
  }
  (void)mesh, (void)part, (void)image;
  return 0;
}
