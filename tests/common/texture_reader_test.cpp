// The "textures" section and textured parameters: images are decoded when the scene loads (so a
// broken one is an error naming the file and the place), each file once however many textures
// name it, kept or dropped as asked, and parameters name textures that exist.
#include <gtest/gtest.h>

#include <string>

#include "common/image/png.h"
#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

fs::path write_scene(TempDir& dir, const std::string& textures) {
  // A 2x1 PNG: one red texel, one blue.
  write_png_rgb8(dir.path() / "two.png", {255, 0, 0, 0, 0, 255}, 2, 1);
  return dir.write("scene.json", R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40},
  "film": {"width": 8, "height": 8},
  "textures": )" + textures + "}");
}

TEST(TextureReaderTest, ImagesAreDecodedOnceAndKeptOrDropped) {
  TempDir dir;
  const fs::path file = write_scene(dir, R"({
    "a": {"type": "image", "file": "two.png", "filter": "nearest", "wrap": "clamp",
          "uv_origin": "top_left", "uv_transform": {"scale": [2, 3], "rotation": 90}},
    "b": {"type": "image", "file": "two.png", "color_space": "linear", "wrap_v": "mirror"},
    "c": {"type": "checkerboard", "color0": [1, 0, 0], "color1": [0, 0, 1]}})");
  const Scene scene = load_scene(file);
  ASSERT_EQ(scene.textures.size(), 3u);
  const TextureDesc &a = scene.textures[0], &b = scene.textures[1], &c = scene.textures[2];
  ASSERT_TRUE(a.image);
  EXPECT_EQ(a.image, b.image) << "one file, one decoded image";
  EXPECT_EQ(a.image->width, 2u);
  EXPECT_EQ(a.image->bytes[0], 255);
  EXPECT_EQ(a.options.filter, TextureFilter::nearest);
  EXPECT_EQ(a.options.wrap_u, TextureWrap::clamp);
  EXPECT_EQ(a.options.wrap_v, TextureWrap::clamp);
  EXPECT_EQ(a.options.origin, UvOrigin::top_left);
  EXPECT_FLOAT_EQ(a.options.transform.scale[1], 3.f);
  EXPECT_NEAR(a.options.transform.rotation, 3.14159265f / 2.f, 1e-6f);
  EXPECT_EQ(b.space, ColourSpace::linear);
  EXPECT_EQ(b.options.wrap_u, TextureWrap::repeat);
  EXPECT_EQ(b.options.wrap_v, TextureWrap::mirror);
  EXPECT_EQ(c.kind, TextureDesc::Kind::kCheckerboard);
  EXPECT_EQ(c.color1, Vec3(0.f, 0.f, 1.f));
  ASSERT_EQ(scene.referenced.size(), 1u);
  EXPECT_EQ(scene.referenced[0], fs::path("two.png"));

  const Scene checked = load_scene(file, {}, SceneImages::kCheckOnly);
  EXPECT_FALSE(checked.textures[0].image);
  EXPECT_EQ(checked.referenced, scene.referenced);
}

void expect_texture_error(const std::string& textures, std::initializer_list<std::string> parts) {
  TempDir dir;
  const fs::path file = write_scene(dir, textures);
  for (SceneImages images : {SceneImages::kKeep, SceneImages::kCheckOnly}) {
    try {
      load_scene(file, {}, images);
      ADD_FAILURE() << "expected an error for " << textures;
    } catch (const SceneError& e) {
      for (const std::string& part : parts)
        EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  }
}

TEST(TextureReaderTest, BadTexturesAreErrorsThatSayWhere) {
  expect_texture_error(R"({"t": {"type": "image", "file": "missing.png"}})",
                       {"/textures/t/file", "missing.png", "not found"});
  expect_texture_error(R"({"t": {"type": "image", "file": "scene.json"}})",
                       {"/textures/t/file", "scene.json"});
  expect_texture_error(R"({"t": {"type": "image", "file": "../x.png"}})", {"/textures/t/file"});
  expect_texture_error(R"({"t": {"type": "noise"}})",
                       {"/textures/t/type", "image or checkerboard"});
  expect_texture_error(R"({"t": {"type": "image", "file": "two.png", "wrap": "tile"}})",
                       {"/textures/t/wrap", "repeat, mirror, clamp"});
  expect_texture_error(R"({"t": {"type": "checkerboard", "color0": [-1, 0, 0]}})",
                       {"/textures/t/color0"});
}

TEST(TextureReaderTest, ACorruptImageIsAnErrorNamingItsFile) {
  TempDir dir;
  const fs::path file = write_scene(dir, R"({"t": {"type": "image", "file": "bad.png"}})");
  std::string png = testing::read_file(dir.path() / "two.png");
  dir.write("bad.png", png.substr(0, png.size() / 2));
  try {
    load_scene(file);
    ADD_FAILURE() << "a truncated PNG loaded";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("/textures/t/file"), std::string::npos) << e.what();
  }
}

TEST(TextureReaderTest, ImagesBeyondTheSampleBudgetAreAnErrorNamingTheTextureAndTheBudget) {
  TempDir dir;
  // Two 2x1 RGB PNGs: 6 bytes of samples each.
  write_png_rgb8(dir.path() / "one.png", {255, 0, 0, 0, 0, 255}, 2, 1);
  write_png_rgb8(dir.path() / "two.png", {0, 255, 0, 0, 0, 255}, 2, 1);
  const scene_json::Json textures = scene_json::Json::parse(R"({
    "a": {"type": "image", "file": "one.png"},
    "again": {"type": "image", "file": "one.png"},
    "b": {"type": "image", "file": "two.png"}})");
  std::vector<std::string> warnings;
  const scene_json::Context context{"scene.json", &warnings};
  const scene_json::Node node(textures, context, "/textures");
  std::vector<TextureDesc> out;
  std::vector<fs::path> referenced;
  // 12 bytes fit a budget of 12: a file named twice counts once.
  TextureReader(dir.path(), SceneImages::kCheckOnly, 12).read(node, out, referenced);
  EXPECT_EQ(out.size(), 3u);
  try {
    out.clear();
    TextureReader(dir.path(), SceneImages::kCheckOnly, 11).read(node, out, referenced);
    ADD_FAILURE() << "12 bytes of samples passed a budget of 11";
  } catch (const SceneError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("scene.json"), std::string::npos) << message;
    EXPECT_NE(message.find("/textures/b/file"), std::string::npos) << message;
    EXPECT_NE(message.find("two.png"), std::string::npos) << message;
    EXPECT_NE(message.find("hold 12 B of samples"), std::string::npos) << message;
    EXPECT_NE(message.find("limit of 11 B"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace rayfarm
