// Keyframed animation in JSON scenes (common/scene/animation.h): values between keys for each
// interpolation, the frame a scene is read at, and every refusal naming its place.
#include <gtest/gtest.h>

#include <cmath>
#include <initializer_list>
#include <string>

#include "common/scene/animation.h"
#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

/// A scene of frames 1-21 (unless `animation` says otherwise) with one sphere and one point light;
/// `camera`, `sphere` and `light` are the members of each, keyframed or not.
std::string animated_scene(const std::string& camera, const std::string& sphere,
                           const std::string& light,
                           const std::string& animation = R"("animation": {"frames": [1, 21]},)") {
  return "{" + animation + R"(
  "camera": {)" +
         camera + R"(, "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
  "film": {"width": 8, "height": 8},
  "materials": {"m": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
  "shapes": [{"type": "sphere", "material": "m", )" +
         sphere + R"(}],
  "lights": [{"type": "point", "position": [0, 4, 0], )" +
         light + R"(}]
})";
}

const std::string kEye = R"("eye": [0, 0, -5])";
const std::string kSphere = R"("center": [0, 0, 0], "radius": 1)";
const std::string kLight = R"("intensity": [1, 1, 1])";

Scene load_at(const std::string& json, std::optional<int64_t> frame) {
  TempDir dir;
  return load_scene(dir.write("scene.json", json), {}, SceneImages::kKeep, {}, {}, frame);
}

void expect_error(const std::string& json, std::optional<int64_t> frame,
                  std::initializer_list<std::string> parts) {
  try {
    (void)load_at(json, frame);
    ADD_FAILURE() << "expected a SceneError for:\n" << json;
  } catch (const SceneError& e) {
    const std::string message = e.what();
    for (const std::string& part : parts) {
      EXPECT_NE(message.find(part), std::string::npos) << "\"" << part << "\" not in: " << message;
    }
  }
}

TEST(Animation, LinearKeysInterpolateAndHoldBeyondTheirEnds) {
  const std::string json = animated_scene(
      R"("eye": {"keyframes": [[5, [0, 0, -5]], [15, [10, 0, -5]]]})", kSphere, kLight);
  EXPECT_FLOAT_EQ(load_at(json, 1).camera.eye.x, 0.f);  // before the first key: its value
  EXPECT_FLOAT_EQ(load_at(json, 5).camera.eye.x, 0.f);
  EXPECT_FLOAT_EQ(load_at(json, 8).camera.eye.x, 3.f);
  EXPECT_FLOAT_EQ(load_at(json, 14).camera.eye.x, 9.f);
  EXPECT_FLOAT_EQ(load_at(json, 21).camera.eye.x, 10.f);  // after the last: its value
  const Scene at = load_at(json, 10);
  ASSERT_TRUE(at.animation.has_value());
  EXPECT_EQ(at.animation->first, 1);
  EXPECT_EQ(at.animation->last, 21);
  EXPECT_EQ(at.frame, 10);
  EXPECT_FLOAT_EQ(at.camera.eye.z, -5.f);
}

TEST(Animation, AnAnimatedSceneIsReadAtItsFirstFrameByDefault) {
  const std::string json =
      animated_scene(R"("eye": {"keyframes": [[1, [2, 0, -5]], [21, [4, 0, -5]]]})", kSphere,
                     kLight, R"("animation": {"frames": [11, 21], "fps": 30},)");
  const Scene scene = load_at(json, std::nullopt);
  EXPECT_EQ(scene.frame, 11);
  EXPECT_FLOAT_EQ(scene.camera.eye.x, 3.f);
  EXPECT_DOUBLE_EQ(scene.animation->fps, 30.0);
  // A still scene has neither.
  const Scene still = load_at(animated_scene(kEye, kSphere, kLight, ""), std::nullopt);
  EXPECT_FALSE(still.animation.has_value());
  EXPECT_FALSE(still.frame.has_value());
}

TEST(Animation, SmoothEasesInAndOutBetweenTwoKeys) {
  const std::string json =
      animated_scene(kEye, R"("center": [0, 0, 0], "radius": {"keyframes": [[1, 1], [21, 3]],
                              "interpolation": "smooth"})",
                     kLight);
  // Zero slope at both ends: 1 + 2 (3 s^2 - 2 s^3) at s = (frame - 1) / 20.
  for (int64_t frame : {1, 2, 6, 11, 16, 20, 21}) {
    const double s = (frame - 1) / 20.0;
    EXPECT_NEAR(load_at(json, frame).spheres.at(0).radius, 1 + 2 * (3 * s * s - 2 * s * s * s),
                1e-6)
        << "frame " << frame;
  }
}

TEST(Animation, SmoothNeverOvershootsItsKeys) {
  // A light switched on and off: keyed at zero, a cubic through the keys would dip below it.
  const std::string json =
      animated_scene(kEye, kSphere,
                     R"("intensity": {"keyframes": [[1, [0, 0, 0]], [3, [8, 8, 8]], [4, [9, 0, 0]],
                                     [12, [0, 1, 0]], [13, [0, 0, 0]]], "interpolation": "smooth"})");
  float previous = -1.f;
  for (int64_t frame = 1; frame <= 21; ++frame) {
    const Vec3 i = load_at(json, frame).point_lights.at(0).intensity;
    EXPECT_GE(i.x, 0.f) << "frame " << frame;
    EXPECT_GE(i.y, 0.f) << "frame " << frame;
    EXPECT_LE(i.x, 9.f) << "frame " << frame;
    EXPECT_LE(i.y, 8.f) << "frame " << frame;
    if (frame <= 4) {
      EXPECT_GE(i.x, previous) << "rising keys give a rising curve, frame " << frame;
    }
    previous = i.x;
  }
}

TEST(Animation, StepHoldsEachKeyUntilTheNext) {
  const std::string json = animated_scene(
      kEye, kSphere,
      R"("intensity": {"keyframes": [[1, [1, 1, 1]], [10, [5, 5, 5]]], "interpolation": "step"})");
  EXPECT_FLOAT_EQ(load_at(json, 9).point_lights.at(0).intensity.x, 1.f);
  EXPECT_FLOAT_EQ(load_at(json, 10).point_lights.at(0).intensity.x, 5.f);
}

TEST(Animation, KeyframedTransformOperationsMoveAShape) {
  const std::string json = animated_scene(kEye,
                                          R"("center": [0, 0, 0], "radius": 1,
         "transform": [{"translate": {"keyframes": [[1, [0, 0, 0]], [21, [0, 4, 0]]]}}])",
                                          kLight);
  EXPECT_NEAR(load_at(json, 1).spheres.at(0).center.y, 0.f, 1e-6);
  EXPECT_NEAR(load_at(json, 6).spheres.at(0).center.y, 1.f, 1e-6);
  EXPECT_NEAR(load_at(json, 21).spheres.at(0).center.y, 4.f, 1e-6);
}

TEST(Animation, FramesOutsideTheAnimationOrOfAStillSceneAreRefused) {
  const std::string animated = animated_scene(kEye, kSphere, kLight);
  expect_error(animated, 22, {"frame 22 is outside the scene's frames 1-21", "/animation/frames"});
  expect_error(animated, 0, {"frame 0 is outside"});
  const std::string still = animated_scene(kEye, kSphere, kLight, "");
  expect_error(still, 1, {"scene.json", "frame 1 was asked for", "still"});
}

TEST(Animation, MalformedKeyframesAndAnimationBlocksNameTheirPlace) {
  const std::string frames = R"("animation": {"frames": [1, 21]},)";
  // Keyframes in a still scene.
  expect_error(animated_scene(R"("eye": {"keyframes": [[1, [0, 0, -5]]]})", kSphere, kLight, ""),
               std::nullopt, {"/camera/eye", "needs an \"animation\" block"});
  // Where every frame must be the same.
  expect_error("{" + frames + R"("film": {"width": {"keyframes": [[1, 8], [2, 16]]}, "height": 8},
                  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0]}})",
               std::nullopt, {"/film/width", "\"film\" cannot be keyframed"});
  expect_error(animated_scene(R"("eye": {"keyframes": [[5, [0, 0, -5]], [5, [1, 0, -5]]]})",
                              kSphere, kLight),
               std::nullopt, {"/camera/eye/keyframes/1/0", "increasing frame order"});
  expect_error(
      animated_scene(R"("eye": {"keyframes": [[1, [0, 0, -5]], [5, [1, 0]]]})", kSphere, kLight),
      std::nullopt, {"/camera/eye/keyframes/1/1", "shape of the first"});
  expect_error(animated_scene(R"("eye": {"keyframes": []})", kSphere, kLight), std::nullopt,
               {"/camera/eye/keyframes", "at least one keyframe"});
  expect_error(animated_scene(R"("eye": {"keyframes": [[1, "a"]]})", kSphere, kLight), std::nullopt,
               {"/camera/eye/keyframes/0/1", "expected a number"});
  expect_error(
      animated_scene(R"("eye": {"keyframes": [[1, [0, 0, -5]]], "interpolation": "cubic"})",
                     kSphere, kLight),
      std::nullopt, {"/camera/eye/interpolation", "unknown interpolation"});
  expect_error(animated_scene(kEye, kSphere, kLight, R"("animation": {"frames": [5, 1]},)"),
               std::nullopt, {"/animation/frames", "comes before the first"});
  expect_error(animated_scene(kEye, kSphere, kLight, R"("animation": {"frames": [1]},)"),
               std::nullopt, {"/animation/frames", "[FIRST, LAST]"});
  expect_error(animated_scene(kEye, kSphere, kLight, R"("animation": {"frames": [1, 2.5]},)"),
               std::nullopt, {"/animation/frames/1"});
}

TEST(Animation, AValueValidAtSomeFramesOnlyFailsAtTheOthersNamingTheFrame) {
  // The radius crosses zero at frame 11.
  const std::string json = animated_scene(
      kEye, R"("center": [0, 0, 0], "radius": {"keyframes": [[1, 1], [21, -1]]})", kLight);
  EXPECT_NEAR(load_at(json, 6).spheres.at(0).radius, 0.5f, 1e-6);
  expect_error(json, 16, {"frame 16 of", "scene.json", "/shapes/0/radius"});
}

TEST(Animation, TheBundledAnimationLoadsAtEveryFrameWithoutWarnings) {
  const fs::path file = fs::path(RAYFARM_SOURCE_DIR) / "scenes" / "animated-box" / "scene.json";
  const auto animation = load_scene_animation(file);
  ASSERT_TRUE(animation.has_value());
  EXPECT_EQ(animation->first, 1);
  EXPECT_EQ(animation->last, 48);
  float previous_light = -1.f;
  for (int64_t frame = animation->first; frame <= animation->last; ++frame) {
    const Scene scene = load_scene(file, {}, SceneImages::kKeep, {}, {}, frame);
    EXPECT_TRUE(scene.warnings.empty()) << "frame " << frame << ": " << scene.warnings.front();
    const float light = scene.point_lights.at(0).intensity.x;
    // The light fades in to frame 12 and out to frame 36, smoothly, never below zero.
    if (frame <= 12) {
      EXPECT_GE(light, previous_light) << frame;
    }
    if (frame > 12 && frame <= 36) {
      EXPECT_LE(light, previous_light) << frame;
    }
    EXPECT_GE(light, 0.f) << frame;
    previous_light = light;
  }
}

TEST(FrameList, ParsesRangesStepsAndSingleFrames) {
  std::string why;
  const auto range = parse_frame_list("1-240", &why);
  ASSERT_TRUE(range) << why;
  EXPECT_EQ(range->count(), 240);
  const auto stepped = parse_frame_list("1-10:3", &why);
  ASSERT_TRUE(stepped) << why;
  EXPECT_EQ(stepped->count(), 4);
  EXPECT_EQ(stepped->at(3), 10);
  EXPECT_EQ(frame_list_name(*stepped), "1-10:3");
  const auto uneven = parse_frame_list("1-11:3", &why);
  ASSERT_TRUE(uneven);
  EXPECT_EQ(uneven->last, 10);  // the last frame rendered
  const auto one = parse_frame_list("7", &why);
  ASSERT_TRUE(one);
  EXPECT_EQ(one->count(), 1);
  EXPECT_EQ(frame_list_name(*one), "7");
  const auto negative = parse_frame_list("-5--1", &why);
  ASSERT_TRUE(negative) << why;
  EXPECT_EQ(negative->first, -5);
  EXPECT_EQ(negative->last, -1);
  for (const char* bad : {"", "a", "1-", "1-2:", "1-2:0", "5-1", "1--", "1-2-3", "1 - 2",
                          "99999999999", "2000000000"}) {
    EXPECT_FALSE(parse_frame_list(bad, &why)) << bad;
    EXPECT_FALSE(why.empty()) << bad;
  }
  EXPECT_FALSE(parse_frame_list("5-1", &why));
  EXPECT_NE(why.find("reversed"), std::string::npos) << why;
}

}  // namespace
}  // namespace rayfarm
