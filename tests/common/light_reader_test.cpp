// The "lights" section: point, spot, directional, environment and constant lights, their keys
// and defaults, the environment's image decoded at load (a broken one is an error naming the
// file and the place), and every refusal saying where.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/image/png.h"
#include "common/scene/parser.h"
#include "tests/support/image_writers.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

fs::path write_scene(TempDir& dir, const std::string& lights) {
  write_png_rgb8(dir.path() / "sky.png", {255, 0, 0, 0, 0, 255}, 2, 1);
  return dir.write("scene.json", R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40},
  "film": {"width": 8, "height": 8},
  "lights": )" + lights + "}");
}

TEST(LightReaderTest, EveryKindWithItsKeysAndDefaults) {
  TempDir dir;
  const fs::path file = write_scene(dir, R"([
    {"type": "point", "position": [1, 2, 3], "intensity": [1, 1, 1]},
    {"type": "spot", "position": [0, 4, 0], "look_at": [0, 0, 0], "intensity": [5, 5, 5],
     "cutoff_angle": 30},
    {"type": "spot", "position": [0, 4, 0], "direction": [0, 0, 2], "intensity": [7, 7, 7],
     "cutoff_angle": 30, "beam_width": 10},
    {"type": "directional", "direction": [0, -3, 0], "irradiance": [2, 2, 2]},
    {"type": "environment", "file": "sky.png", "scale": 2.5,
     "transform": {"rotate": {"axis": [0, 1, 0], "angle": 90}}}])");
  const Scene s = load_scene(file);
  ASSERT_EQ(s.point_lights.size(), 1u);
  ASSERT_EQ(s.spot_lights.size(), 2u);
  EXPECT_EQ(s.spot_lights[0].direction, Vec3(0.f, -1.f, 0.f));
  EXPECT_FLOAT_EQ(s.spot_lights[0].cutoff_deg, 30.f);
  EXPECT_FLOAT_EQ(s.spot_lights[0].beam_width_deg, 22.5f) << "default: 3/4 of the cutoff";
  EXPECT_EQ(s.spot_lights[1].direction, Vec3(0.f, 0.f, 1.f));
  EXPECT_FLOAT_EQ(s.spot_lights[1].beam_width_deg, 10.f);
  EXPECT_EQ(s.spot_lights[1].intensity, Vec3(7.f));
  ASSERT_EQ(s.directional_lights.size(), 1u);
  EXPECT_EQ(s.directional_lights[0].direction, Vec3(0.f, -1.f, 0.f));
  ASSERT_TRUE(s.environment);
  EXPECT_EQ(s.environment->file, fs::path("sky.png"));
  ASSERT_TRUE(s.environment->image);
  EXPECT_EQ(s.environment->image->width, 2u);
  EXPECT_EQ(s.environment->scale, Vec3(2.5f));
  EXPECT_NEAR(s.environment->rotation[2], 1.0, 1e-12) << "90 degrees about +y takes z to x";
  ASSERT_EQ(s.referenced.size(), 1u);
  EXPECT_EQ(s.referenced[0], fs::path("sky.png"));

  const Scene checked = load_scene(file, {}, SceneImages::kCheckOnly);
  ASSERT_TRUE(checked.environment);
  EXPECT_FALSE(checked.environment->image);
  EXPECT_EQ(checked.referenced, s.referenced);
}

TEST(LightReaderTest, ConstantEnvironment) {
  TempDir dir;
  const Scene s =
      load_scene(write_scene(dir, R"([{"type": "constant", "radiance": [0.5, 1, 2]}])"));
  ASSERT_TRUE(s.environment);
  EXPECT_TRUE(s.environment->file.empty());
  EXPECT_EQ(s.environment->scale, Vec3(0.5f, 1.f, 2.f));
  EXPECT_TRUE(s.referenced.empty());
}

void expect_light_error(const std::string& lights, std::initializer_list<std::string> parts,
                        const std::string& corrupt = "") {
  TempDir dir;
  const fs::path file = write_scene(dir, lights);
  if (!corrupt.empty()) dir.write(corrupt, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X");
  for (SceneImages images : {SceneImages::kKeep, SceneImages::kCheckOnly}) {
    try {
      load_scene(file, {}, images);
      ADD_FAILURE() << "expected an error for " << lights;
    } catch (const SceneError& e) {
      for (const std::string& part : parts)
        EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  }
}

TEST(LightReaderTest, BadLightsAreErrorsThatSayWhere) {
  expect_light_error(R"([{"type": "environment", "file": "missing.hdr"}])",
                     {"/lights/0/file", "missing.hdr"});
  expect_light_error(R"([{"type": "environment", "file": "bad.hdr"}])",
                     {"/lights/0/file", "bad.hdr"}, "bad.hdr");
  expect_light_error(R"([{"type": "environment"}])", {"/lights/0", "file"});
  expect_light_error(R"([{"type": "constant", "radiance": [1, 1, 1]},
                         {"type": "environment", "file": "sky.png"}])",
                     {"/lights/1", "at most one environment", "lights[0]"});
  expect_light_error(R"([{"type": "environment", "file": "sky.png",
                          "transform": {"scale": [2, 2, 2]}}])",
                     {"/lights/0/transform", "rotation"});
  expect_light_error(R"([{"type": "environment", "file": "sky.png",
                          "transform": {"translate": [0, 1, 0]}}])",
                     {"/lights/0/transform", "translation"});
  expect_light_error(R"([{"type": "environment", "file": "sky.png", "scale": -1}])",
                     {"/lights/0/scale"});
  expect_light_error(R"([{"type": "constant", "radiance": [-1, 0, 0]}])", {"/lights/0/radiance"});
  expect_light_error(R"([{"type": "spot", "position": [0, 0, 0], "direction": [0, 0, 1],
                          "intensity": [1, 1, 1], "cutoff_angle": 120}])",
                     {"/lights/0/cutoff_angle", "(0, 90]"});
  expect_light_error(R"([{"type": "spot", "position": [0, 0, 0], "direction": [0, 0, 1],
                          "intensity": [1, 1, 1], "cutoff_angle": 20, "beam_width": 30}])",
                     {"/lights/0/beam_width", "must not exceed cutoff_angle"});
  expect_light_error(R"([{"type": "spot", "position": [0, 0, 0], "direction": [0, 0, 0],
                          "intensity": [1, 1, 1]}])",
                     {"/lights/0/direction", "zero"});
  expect_light_error(R"([{"type": "spot", "position": [0, 0, 0], "intensity": [1, 1, 1]}])",
                     {"/lights/0", "direction"});
  expect_light_error(R"([{"type": "spot", "position": [1, 1, 1], "look_at": [1, 1, 1],
                          "intensity": [1, 1, 1]}])",
                     {"/lights/0/look_at", "equals position"});
  expect_light_error(
      R"([{"type": "directional", "direction": [0, 0, 0], "irradiance": [1, 1, 1]}])",
      {"/lights/0/direction", "zero"});
  expect_light_error(R"([{"type": "area"}])",
                     {"/lights/0/type", "point, spot, projector, directional, environment"});
}

/// A scene with the texture "sky" (sky.png) and `lights`.
fs::path write_textured_scene(TempDir& dir, const std::string& lights) {
  write_png_rgb8(dir.path() / "sky.png", {255, 0, 0, 0, 0, 255}, 2, 1);
  return dir.write("scene.json", R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40},
  "film": {"width": 8, "height": 8},
  "textures": {"sky": {"type": "image", "file": "sky.png"}},
  "lights": )" + lights + "}");
}

// A spot may cast an image over its cone, and a projector casts one through a camera's frustum:
// the image's frame has y along "up" and x to the right seen from the light, u and v growing
// along them, so that an image lands upright as a camera there would see it.
TEST(LightReaderTest, SpotsAndProjectorsCastImagesUpright) {
  TempDir dir;
  const Scene s = load_scene(write_textured_scene(dir, R"([
    {"type": "projector", "position": [0, 0, 5], "look_at": [0, 0, 0], "fov": 90, "aspect": 2,
     "image": {"texture": "sky"}, "intensity": 3},
    {"type": "spot", "position": [0, 4, 0], "direction": [0, -1, 0], "intensity": [1, 1, 1],
     "cutoff_angle": 45, "image": [0.5, 0.5, 0.5], "up": [0, 0, -1]},
    {"type": "spot", "position": [0, 4, 0], "direction": [0, -1, 0], "intensity": [1, 1, 1]}])"));
  ASSERT_EQ(s.spot_lights.size(), 3u);
  const SpotLight& projector = s.spot_lights[0];
  ASSERT_TRUE(projector.image.has_value());
  EXPECT_TRUE(projector.image->projector);
  EXPECT_EQ(projector.direction, Vec3(0.f, 0.f, -1.f));
  EXPECT_EQ(projector.image->y_axis, Vec3(0.f, 1.f, 0.f));
  EXPECT_EQ(projector.image->x_axis, Vec3(1.f, 0.f, 0.f)) << "looking along -z, right is +x";
  EXPECT_FLOAT_EQ(projector.image->u_scale, 0.25f) << "tan_x = aspect x tan(45) = 2";
  EXPECT_FLOAT_EQ(projector.image->v_scale, 0.5f);
  EXPECT_EQ(projector.image->image.texture, 0);
  EXPECT_EQ(projector.intensity, Vec3(3.f));
  EXPECT_NEAR(projector.cutoff_deg, std::atan(std::sqrt(5.0)) * 180.0 / 3.14159265358979, 1e-4);
  const SpotLight& spot = s.spot_lights[1];
  ASSERT_TRUE(spot.image.has_value());
  EXPECT_FALSE(spot.image->projector);
  EXPECT_EQ(spot.image->y_axis, Vec3(0.f, 0.f, -1.f));
  EXPECT_FLOAT_EQ(spot.image->u_scale, 0.5f) << "0.5 / tan(45 degrees)";
  EXPECT_EQ(spot.image->image.value, Vec3(0.5f));
  EXPECT_FALSE(s.spot_lights[2].image.has_value());

  const auto expect_error = [](const std::string& lights,
                               std::initializer_list<const char*> parts) {
    TempDir d;
    const fs::path file = write_textured_scene(d, lights);
    try {
      (void)load_scene(file);
      ADD_FAILURE() << "loaded: " << lights;
    } catch (const SceneError& e) {
      for (const char* part : parts)
        EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  const std::string projector_at = R"({"type": "projector", "position": [0, 0, 5], )";
  expect_error("[" + projector_at + R"("direction": [0, 0, -1], "image": [1, 1, 1]}])",
               {"/lights/0", "missing key \"fov\""});
  expect_error("[" + projector_at + R"("direction": [0, 0, -1], "fov": 180, "image": 1}])",
               {"/lights/0/fov", "(0, 180)"});
  expect_error("[" + projector_at + R"("direction": [0, 0, -1], "fov": 60, "aspect": 1e6,
               "image": [1, 1, 1]}])",
               {"/lights/0/aspect"});
  expect_error("[" + projector_at + R"("direction": [0, 0, -1], "fov": 60, "up": [0, 0, 2],
               "image": [1, 1, 1]}])",
               {"/lights/0/up", "parallel"});
  expect_error("[" + projector_at + R"("direction": [0, 0, -1], "fov": 60,
               "image": {"texture": "nope"}}])",
               {"/lights/0/image", "nope"});
  expect_error(R"([{"type": "spot", "position": [0, 4, 0], "direction": [0, -1, 0],
               "intensity": [1, 1, 1], "cutoff_angle": 90, "image": [1, 1, 1]}])",
               {"/lights/0", "below 90"});
}

TEST(LightReaderTest, BundledEnvironmentSceneLoadsWithItsSky) {
  const Scene s =
      load_scene(fs::path(RAYFARM_SOURCE_DIR) / "scenes" / "environment" / "scene.json");
  EXPECT_TRUE(s.warnings.empty());
  ASSERT_TRUE(s.environment);
  ASSERT_TRUE(s.environment->image);
  EXPECT_EQ(s.environment->image->width, 64u);
  EXPECT_EQ(s.environment->image->height, 32u);
  EXPECT_STREQ(s.environment->image->format, "Radiance HDR");
  EXPECT_EQ(s.referenced, std::vector<fs::path>{"sky.hdr"});
  EXPECT_EQ(s.spheres.size(), 3u);
}

/// A 2x1 Radiance HDR, flat: the first texel grey with RGBE exponent `exponent` (radiance about
/// 2^(exponent - 129)), the second dim.
std::string hdr_with_exponent(uint8_t exponent) {
  std::string file = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n";
  for (uint8_t b : {uint8_t{128}, uint8_t{128}, uint8_t{128}, exponent, uint8_t{128}, uint8_t{128},
                    uint8_t{128}, uint8_t{120}})
    file.push_back(static_cast<char>(b));
  return file;
}

TEST(LightReaderTest, AnEnvironmentWhosePowerOverflowsIsAnErrorNamingTheFile) {
  TempDir dir;
  dir.write("huge.hdr", hdr_with_exponent(250));  // about 2.7e36
  // Within float range: loads, with no warning.
  const Scene ok = load_scene(write_scene(dir, R"([{"type": "environment", "file": "huge.hdr",
                                                   "scale": 100}])"));
  ASSERT_TRUE(ok.environment);
  EXPECT_TRUE(ok.warnings.empty()) << ok.warnings.front();
  // Times 1000 the luminance is beyond 3.4e38.
  const fs::path file = write_scene(dir, R"([{"type": "environment", "file": "huge.hdr",
                                              "scale": 1000}])");
  for (SceneImages images : {SceneImages::kKeep, SceneImages::kCheckOnly}) {
    try {
      load_scene(file, {}, images);
      ADD_FAILURE() << "an environment of infinite power loaded";
    } catch (const SceneError& e) {
      const std::string message = e.what();
      for (const char* part : {"/lights/0/file", "huge.hdr", "(0, 0)", "beyond the float range"})
        EXPECT_NE(message.find(part), std::string::npos) << message;
    }
  }
}

TEST(LightReaderTest, NonFiniteEnvironmentSamplesAreAWarningNamingTheFile) {
  TempDir dir;
  const std::vector<float> samples = {1.f, std::nanf(""), 1.f, -2.f, 0.5f, 0.5f};
  const auto exr = testing::encode_exr(samples, 2, 1, {"R", "G", "B"}, false);
  dir.write("nan.exr", std::string(exr.begin(), exr.end()));
  const Scene s = load_scene(write_scene(dir, R"([{"type": "environment", "file": "nan.exr"}])"));
  ASSERT_EQ(s.warnings.size(), 1u);
  for (const char* part : {"/lights/0/file", "nan.exr", "2 sample(s)", "taken as black"})
    EXPECT_NE(s.warnings[0].find(part), std::string::npos) << s.warnings[0];
}

}  // namespace
}  // namespace rayfarm
