// Hostile and malformed scene input (docs/stability.md): every file is either loaded (with
// warnings naming file and place) or rejected with a SceneError naming the file and the JSON
// pointer or line; never a crash, an abort, a hang or another exception. Complements
// scene_parser_test.cpp, which covers the common mistakes.
#include <gtest/gtest.h>

#include <filesystem>
#include <initializer_list>
#include <string>

#include "common/scene/parser.h"
#include "common/scene/text_lines.h"
#include "common/util/utf8.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

constexpr const char* kCamera =
    R"("camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40}, "film": {"width": 4, "height": 4})";
constexpr const char* kMaterial = R"("materials": {"m": {"type": "diffuse"}})";

/// A scene file: camera, film and `extra` members.
std::string scene(const std::string& extra) {
  return std::string("{") + kCamera + (extra.empty() ? "" : ", " + extra) + "}";
}

/// The SceneError message of loading `file`, or "" (with a test failure) when it loads.
std::string error_of(const fs::path& file) {
  try {
    (void)load_scene(file);
  } catch (const SceneError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "not a SceneError: " << e.what();
    return e.what();
  }
  ADD_FAILURE() << "loaded, expected an error: " << file;
  return "";
}

/// Expects loading `file` to fail with a message holding every one of `parts`.
void expect_error(const fs::path& file, std::initializer_list<std::string> parts) {
  const std::string message = error_of(file);
  for (const std::string& part : parts) {
    EXPECT_NE(message.find(part), std::string::npos) << "\"" << part << "\" not in: " << message;
  }
}

/// Expects a scene with `extra` members to fail naming scene.json and every one of `parts`.
void expect_scene_error(const std::string& extra, std::initializer_list<std::string> parts) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", scene(extra));
  const std::string message = error_of(file);
  EXPECT_EQ(message.rfind(file.string() + ": ", 0), 0u) << message;
  for (const std::string& part : parts) {
    EXPECT_NE(message.find(part), std::string::npos) << "\"" << part << "\" not in: " << message;
  }
}

std::string joined(const std::vector<std::string>& lines) {
  std::string all;
  for (const std::string& l : lines) all += l + "\n";
  return all;
}

// ---- unknown keys ----------------------------------------------------------------------------

TEST(HostileScene, UnknownKeysAnywhereAreWarningsWithTheirPointer) {
  TempDir dir;
  dir.write("m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const fs::path file = dir.write("scene.json", R"({
    "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40, "zoom": 2},
    "film": {"width": 4, "height": 4, "dpi": 300},
    "materials": {"m": {"type": "diffuse", "roughness": 0.5}},
    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m", "uv": 1},
               {"type": "mesh", "file": "m.obj", "smooth": true}],
    "lights": [{"type": "point", "position": [0, 2, 0], "intensity": [1, 1, 1], "cone": 30}],
    "render": {"spp": 4, "denoise": true},
    "a/b~c": 1, "ctrl\u0001": 2, "": 3
  })");
  const Scene s = load_scene(file);
  const std::string all = joined(s.warnings);
  for (const char* pointer :
       {": /camera/zoom: unknown key \"zoom\"", ": /film/dpi: unknown key", ": /materials/m/roughness:",
        ": /shapes/0/uv:", ": /shapes/1/smooth:", ": /lights/0/cone:", ": /render/denoise:",
        ": /a~1b~0c: unknown key \"a/b~c\"", ": /ctrl?: unknown key \"ctrl?\"", ": /: unknown key \"\""}) {
    EXPECT_NE(all.find(file.string() + pointer), std::string::npos) << pointer << " not in\n" << all;
  }
  EXPECT_EQ(s.warnings.size(), 10u) << all;
}

// ---- wrong types ------------------------------------------------------------------------------

TEST(HostileScene, WrongTypesNameTheirPointer) {
  struct Case {
    std::string extra, pointer, what;
  };
  const Case cases[] = {
      {R"("materials": [])", "/materials", "expected an object, got an array"},
      {R"("materials": {"m": "diffuse"})", "/materials/m", "expected an object, got string"},
      {R"("materials": {"m": {"type": 1}})", "/materials/m/type", "expected a string, got number 1"},
      {R"("materials": {"m": {"type": "diffuse", "two_sided": "yes"}})", "/materials/m/two_sided",
       "expected true or false"},
      {R"("materials": {"m": {"type": "diffuse", "albedo": {"r": 1}}})", "/materials/m/albedo",
       "expected an array"},
      {R"("materials": {"m": {"type": "diffuse", "albedo": [0.5, 0.5, null]}})",
       "/materials/m/albedo/2", "expected a number, got null"},
      {R"("materials": {"m": {"type": "diffuse", "albedo": [[0.5], 0.5, 0.5]}})",
       "/materials/m/albedo/0", "expected a number, got an array"},
      {R"("shapes": {"type": "sphere"})", "/shapes", "expected an array"},
      {R"("shapes": [42])", "/shapes/0", "expected an object, got number 42"},
      {std::string(kMaterial) + R"(, "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": "1", "material": "m"}])",
       "/shapes/0/radius", "expected a number, got string \"1\""},
      {std::string(kMaterial) + R"(, "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": 0}])",
       "/shapes/0/material", "expected a string"},
      {R"("shapes": [{"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0]], "material": "m"}])",
       "/shapes/0/vertices", "expected 3 vertices"},
      {R"("shapes": [{"type": "mesh", "file": ["m.obj"]}])", "/shapes/0/file", "expected a string"},
      {R"("lights": {"type": "point"})", "/lights", "expected an array"},
      {R"("background": "black")", "/background", "expected an array"},
      {R"("render": [64])", "/render", "expected an object"},
      {R"("render": {"integrator": 3})", "/render/integrator", "expected a string"},
      {R"("render": {"spp": true})", "/render/spp", "expected an integer, got true"},
      {R"("format": "1")", "/format", "expected an integer"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.extra);
    expect_scene_error(c.extra, {": " + c.pointer + ": ", c.what});
  }
  TempDir dir;
  expect_error(dir.write("scene.json", R"({"camera": [0, 0, 0], "film": {"width": 1, "height": 1}})"),
               {": /camera: expected an object"});
  expect_error(dir.write("scene.json", R"({"camera": {"eye": [0, 0, 0], "look_at": [0, 0, 1],
               "fov_y": 40}, "film": {"width": "4", "height": 4}})"),
               {": /film/width: expected an integer, got string \"4\""});
  expect_error(dir.write("scene.json", "null"), {"(top level): expected an object, got null"});
  expect_error(dir.write("scene.json", "\"scene\""), {"(top level): expected an object"});
}

// ---- huge and tiny numbers ----------------------------------------------------------------------

TEST(HostileScene, HugeAndTinyNumbersAreRangeErrors) {
  const std::string sphere = std::string(kMaterial) + R"(, "shapes": [{"type": "sphere", "material": "m", )";
  expect_scene_error(sphere + R"("center": [0, 1e308, 0], "radius": 1}])",
                     {"/shapes/0/center/1", "out of range"});
  expect_scene_error(sphere + R"("center": [0, 0, 0], "radius": 1e-300}])",
                     {"/shapes/0/radius", "must be positive"});
  expect_scene_error(sphere + R"("center": [0, 0, 0], "radius": 1e18}])",
                     {"/shapes/0/radius", "beyond 1e17"});
  expect_scene_error(sphere + R"("center": [-2e17, 0, 0], "radius": 1}])",
                     {"/shapes/0/center/0", "beyond 1e17"});
  expect_scene_error(R"("shapes": [{"type": "quad", "corner": [0, 0, 0], "edge1": [1e20, 0, 0],
                     "edge2": [0, 1, 0], "material": "m"}])",
                     {"/shapes/0/edge1/0", "beyond 1e17"});
  expect_scene_error(R"("lights": [{"type": "point", "position": [0, 0, 1e29], "intensity": [1, 1, 1]}])",
                     {"/lights/0/position/2", "beyond 1e17"});
  expect_scene_error(R"("background": [1e31, 0, 0])", {"/background/0", "out of range"});
  expect_scene_error(R"("background": [1e999, 0, 0])", {"invalid JSON"});
  expect_scene_error(R"("background": [-1, 0, 0])", {"/background/0", "negative"});
  expect_scene_error(R"("render": {"spp": 18446744073709551616})", {"/render/spp", "integer"});
  expect_scene_error(R"("render": {"spp": 4294967297})", {"/render/spp", "from 1 to 16777216"});
  expect_scene_error(R"("render": {"max_depth": -9223372036854775809})", {"/render/max_depth"});
  expect_scene_error(R"("render": {"max_depth": 1000001})", {"/render/max_depth", "0 to 1000000"});
  expect_scene_error(R"("render": {"max_depth": "infinite"})", {"/render/max_depth", "unlimited"});
  expect_scene_error(R"("render": {"roulette_depth": -1})", {"/render/roulette_depth"});
  expect_scene_error(R"("render": {"sampler": "halton"})", {"/render/sampler", "sobol"});
  expect_scene_error(R"("render": {"roulette": "none"})", {"/render/roulette", "throughput"});
  expect_scene_error(R"("render": {"seed": 18446744073709551616})", {"/render/seed", "unsigned"});
  expect_scene_error(R"("format": 99999999999999999999)", {"/format"});
  expect_scene_error("\"background\": [" + std::string(400, '9') + ", 0, 0]",
                     {"invalid JSON", "number overflow"});
  // 100000 digits after the point, and -1e-999, underflow to (negative) zero: a valid, black
  // background.
  TempDir dir;
  const Scene s = load_scene(dir.write(
      "s.json", scene("\"background\": [0." + std::string(100000, '0') + "1, -1e-999, 0]")));
  EXPECT_EQ(s.background, Vec3(0.f));
}

// ---- sizes that claim gigabytes ----------------------------------------------------------------

/// A sparse file of `bytes` bytes: it claims the size without using the disk.
fs::path sparse_file(const TempDir& dir, const std::string& name, std::uintmax_t bytes) {
  const fs::path file = dir.write(name, "v 0 0 0\n");
  fs::resize_file(file, bytes);
  return file;
}

TEST(HostileScene, FilesClaimingGigabytesAreRefusedBeforeReading) {
  constexpr std::uintmax_t k2GiB = std::uintmax_t{2} << 30;
  TempDir dir;
  const fs::path big_scene = sparse_file(dir, "big.json", k2GiB);
  expect_error(big_scene, {big_scene.string(), "2147483648 bytes", "limit of 67108864"});

  sparse_file(dir, "big.obj", k2GiB);
  const fs::path with_obj =
      dir.write("obj.json", scene(R"("shapes": [{"type": "mesh", "file": "big.obj"}])"));
  expect_error(with_obj, {"big.obj: the file has 2147483648 bytes", "limit of 1073741824"});

  sparse_file(dir, "big.mtl", k2GiB);
  dir.write("small.obj", "mtllib big.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const fs::path with_mtl =
      dir.write("mtl.json", scene(R"("shapes": [{"type": "mesh", "file": "small.obj"}])"));
  expect_error(with_mtl, {"big.mtl: the file has 2147483648 bytes", "limit of 16777216"});

  // Film sizes and element counts that claim gigapixels.
  expect_error(dir.write("film.json", R"({"camera": {"eye": [0, 0, 0], "look_at": [0, 0, 1],
               "fov_y": 40}, "film": {"width": 2147483648, "height": 1}})"),
               {": /film/width", "1 to 16384"});
  expect_error(dir.write("film2.json", R"({"camera": {"eye": [0, 0, 0], "look_at": [0, 0, 1],
               "fov_y": 40}, "film": {"width": 16384, "height": 4097}})"),
               {": /film", "2^26"});
}

// ---- OBJ and MTL: truncated, out of range, not UTF-8 --------------------------------------------

/// Loads a scene with one mesh "m.obj" holding `obj` (and "m.mtl" holding `mtl`); expects an
/// error naming "m.obj:LINE" (or `file`:LINE) and `what`.
void expect_obj_error(const std::string& obj, size_t line, const std::string& what,
                      const std::string& mtl = "newmtl a\nKd 0.5 0.5 0.5\n",
                      const std::string& file = "m.obj") {
  TempDir dir;
  dir.write("m.obj", obj);
  dir.write("m.mtl", mtl);
  const fs::path scene_file =
      dir.write("scene.json", scene(R"("shapes": [{"type": "mesh", "file": "m.obj"}])"));
  expect_error(scene_file,
               {(dir.path() / file).string() + ":" + std::to_string(line) + ": ", what});
}

TEST(HostileObj, TruncatedStatements) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  expect_obj_error(tri + "f 1 2 3/", 4, "malformed face vertex \"3/\"");
  expect_obj_error(tri + "f 1 2 3//", 4, "malformed face vertex");
  expect_obj_error(tri + "f 1 2 /3", 4, "malformed face vertex");
  expect_obj_error(tri + "f 1 2 3/1/1/1", 4, "malformed face vertex");
  expect_obj_error(tri + "f", 4, "face with 0 vertices");
  expect_obj_error(tri + "v 1 2", 4, "expected 3 coordinates");
  expect_obj_error(tri + "v 1 2 3 4 5", 4, "expected 3, 4 or 6 values, got 5");
  expect_obj_error(tri + "vt", 4, "expected 1 to 3 texture coordinates");
  expect_obj_error(tri + "vn 0 1", 4, "3 normal components");
  expect_obj_error(tri + "v 1e 0 0", 4, "\"1e\" is not a finite number");
  expect_obj_error(tri + "v 0x10 0 0", 4, "not a finite number");
  expect_obj_error(tri + "mtllib", 4, "mtllib without a file name");
  expect_obj_error("mtllib m.mtl\n" + tri + "usemtl a\nf 1 2 3\n", 1, "newmtl without", "newmtl\n",
                   "m.mtl");
  expect_obj_error("mtllib m.mtl\n" + tri + "usemtl a\nf 1 2 3\n", 2, "Kd: expected 3 numbers",
                   "newmtl a\nKd 0.5", "m.mtl");
  expect_obj_error("mtllib m.mtl\n" + tri + "usemtl a\nf 1 2 3\n", 2, "illum", "newmtl a\nillum",
                   "m.mtl");
}

TEST(HostileObj, IndicesOutOfRange) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  expect_obj_error(tri + "f 1 2 2147483648\n", 4, "vertex index 2147483648 is out of range: 3");
  expect_obj_error(tri + "f 1 2 -2147483649\n", 4, "vertex index -2147483649 is out of range");
  expect_obj_error(tri + "f 1 2 9223372036854775807\n", 4, "out of range");
  expect_obj_error(tri + "f 1 2 -9223372036854775808\n", 4, "out of range");
  expect_obj_error(tri + "f 1/1 2/1 3/1\n", 4, "texture coordinate index 1 is out of range: 0");
  expect_obj_error(tri + "vt 0 0\nf 1/1 2/2 3/1\n", 5, "texture coordinate index 2 is out of range");
  expect_obj_error(tri + "f 1 2 +3\n", 4, "malformed vertex index \"+3\"");
  expect_obj_error(tri + "f 1 2 3.0\n", 4, "malformed vertex index");
}

TEST(HostileObj, ANameCutShortInAMessageStaysUtf8) {
  // 59 bytes, then a two-byte character across the cut at 60: the cut moves before it.
  const std::string name = std::string(59, 'a') + "\xc3\xa9" + "tail";
  const std::string quoted = scene_text::in_quotes(name);
  EXPECT_EQ(quoted, "\"" + std::string(59, 'a') + "...\"");
  EXPECT_EQ(invalid_utf8_at(quoted), std::string_view::npos);
  EXPECT_EQ(scene_text::in_quotes("short \xc3\xa9"), "\"short \xc3\xa9\"");
}

TEST(HostileObj, BytesThatAreNotUtf8) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  expect_obj_error(tri + "o \xc0\xaf\n", 4, "invalid UTF-8 byte 0xC0 at column 3");      // overlong
  expect_obj_error(tri + "o \xed\xa0\x80\n", 4, "invalid UTF-8 byte 0xED");               // surrogate
  expect_obj_error(tri + "o \xf8\x88\x80\x80\x80\n", 4, "invalid UTF-8 byte 0xF8");       // 5 bytes
  expect_obj_error(tri + "o \xf4\x90\x80\x80\n", 4, "invalid UTF-8 byte 0xF4");           // > U+10FFFF
  expect_obj_error(tri + "o ok\xe2\x82", 4, "invalid UTF-8 byte 0xE2 at column 5");       // cut at EOF
  expect_obj_error(tri + "o a\rb\n", 4, "carriage return");
  expect_obj_error("mtllib m.mtl\n" + tri + "usemtl a\nf 1 2 3\n", 1, "invalid UTF-8 byte 0xFF",
                   "newmtl \xff\n", "m.mtl");
  // Valid multi-byte UTF-8 in names is fine.
  TempDir dir;
  dir.write("m.obj", "mtllib m.mtl\n" + tri + "usemtl caf\xc3\xa9\xf0\x9f\x98\x80\nf 1 2 3\n");
  dir.write("m.mtl", "newmtl caf\xc3\xa9\xf0\x9f\x98\x80\nKd 0.5 0.5 0.5\n");
  const Scene s = load_scene(dir.write("s.json", scene(R"("shapes": [{"type": "mesh", "file": "m.obj"}])")));
  EXPECT_EQ(s.materials.at(0).name, "m.obj:caf\xc3\xa9\xf0\x9f\x98\x80");
  // usemtl reads one word (as most OBJ readers do) while newmtl names run to the end of the line:
  // a name with a space cannot be used, and the error names the line.
  expect_obj_error("mtllib m.mtl\n" + tri + "usemtl my name\nf 1 2 3\n", 5,
                   "usemtl \"my\": no material", "newmtl my name\nKd 0.5 0.5 0.5\n");
}

TEST(HostileScene, JsonThatIsNotUtf8) {
  TempDir dir;
  for (const std::string& bad : {std::string("\xc0\xaf"), std::string("\xed\xa0\x80"),
                                std::string("\xff"), std::string("\xe2\x82")}) {
    expect_error(dir.write("a.json", scene("\"x" + bad + "\": 1")), {"a.json: invalid JSON", "UTF-8"});
    expect_error(dir.write("b.json", scene(std::string(kMaterial).substr(0, 16) + bad + "\": {}}")),
                 {"b.json: invalid JSON"});
  }
  // A mesh path with bytes that are not UTF-8 in \u escapes: a lone surrogate.
  expect_error(dir.write("c.json", scene(R"("shapes": [{"type": "mesh", "file": "\ud800.obj"}])")),
               {"c.json: invalid JSON"});
}

// ---- paths --------------------------------------------------------------------------------------

TEST(HostileScene, PathsThatEscapeOrAreNotFiles) {
  TempDir dir;
  dir.write("x.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  fs::create_directories(dir.path() / "sub" / "folder.obj");
  const auto mesh = [&](const std::string& path) {
    return dir.write("sub/scene.json",
                     scene(R"("shapes": [{"type": "mesh", "file": )" + path + "}]"));
  };
  expect_error(mesh(R"("./../x.obj")"), {"/shapes/0/file", "leaves the scene's folder"});
  expect_error(mesh(R"("a/b/../../../x.obj")"), {"/shapes/0/file", "leaves the scene's folder"});
  expect_error(mesh(R"("..")"), {"/shapes/0/file", "leaves the scene's folder"});
  expect_error(mesh(R"("/etc/passwd")"), {"/shapes/0/file", "absolute"});
  expect_error(mesh(R"("//server/share/x.obj")"), {"/shapes/0/file", "absolute"});
  expect_error(mesh(R"("a\u0000b.obj")"), {"/shapes/0/file", "NUL"});
  expect_error(mesh(R"(".")"), {"/shapes/0/file", "names a folder"});
  expect_error(mesh(R"("folder.obj/")"), {"/shapes/0/file", "names a folder"});
  expect_error(mesh(R"("folder.obj")"), {"folder.obj", "not a regular file"});
  expect_error(mesh(R"("..\\x.obj")"), {"/shapes/0/file", "not found"});
  expect_error(mesh("\"" + std::string(5000, 'a') + ".obj\""), {"/shapes/0/file", "not found"});
  // mtllib paths follow the same rules, relative to the OBJ's folder.
  for (const char* name : {"/etc/passwd", "../../m.mtl", "sub/../../../m.mtl"}) {
    dir.write("sub/m.obj", std::string("mtllib ") + name + "\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_error(mesh(R"("m.obj")"), {"m.obj:1: mtllib \"" + std::string(name) + "\""});
  }
}

// ---- data that is well formed but degenerate: warnings -----------------------------------------

TEST(HostileObj, ZeroLengthNormalsAndZeroAreaFacesAreWarnings) {
  TempDir dir;
  dir.write("m.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nvn 0 0 0\nvn 0 0 1\nvn 0 0 0\n"
            "f 1//1 2//2 3//1\nf 1 2 4\nf 1 1 1\n");
  const fs::path file = dir.write("scene.json", scene(R"("shapes": [{"type": "mesh", "file": "m.obj"}])"));
  const Scene s = load_scene(file);
  const std::string all = joined(s.warnings);
  EXPECT_NE(all.find("m.obj:5: vn has zero length"), std::string::npos) << all;
  EXPECT_EQ(all.find("m.obj:7:"), std::string::npos) << "one warning per file\n" << all;
  EXPECT_NE(all.find("m.obj: 2 zero-area triangle(s) dropped"), std::string::npos) << all;
  ASSERT_EQ(s.meshes.size(), 1u);
  EXPECT_EQ(s.meshes[0].triangle_count(), 1u);
  // Vertices beyond the geometry limit are errors with their line.
  expect_obj_error("v 0 0 0\nv 1 0 0\nv 0 2e17 0\nf 1 2 3\n", 3, "beyond 1e17");
}

}  // namespace
}  // namespace rayfarm
