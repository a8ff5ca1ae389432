// glTF animations (common/scene/gltf_animation.h): node translations, rotations and scales keyed
// LINEAR, STEP and CUBICSPLINE, posed at a frame (24 a second from time 0 for a file rendered
// directly, the JSON scene's frames for one it names); malformed animations name their place.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/scene/parser.h"
#include "tests/support/gltf_builder.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

using testing::GltfBuilder;
using testing::TempDir;
using Json = nlohmann::json;

constexpr double kPi = 3.14159265358979323846;

/// A unit quad (node 0) moved from x = 0 to x = 2 over a second (LINEAR) and scaled by 3 from
/// half a second on (STEP, a second animation); a camera (node 1) at z = 10 turning from looking
/// down -z to looking down -x over the same second (LINEAR rotation).
GltfBuilder animated() {
  GltfBuilder b;
  const int mesh = b.add_quad(-1);
  b.push("nodes", {{"mesh", mesh}});
  b.push("cameras", {{"type", "perspective"},
                     {"perspective", {{"yfov", kPi / 4}, {"aspectRatio", 1.0}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 0}, {"translation", {0, 0, 10}}});
  b.doc["scenes"] = {{{"nodes", {0, 1}}}};
  b.doc["scene"] = 0;
  const int times = b.add_floats({0.f, 1.f}, "SCALAR");
  const int moves = b.add_floats({0, 0, 0, 2, 0, 0}, "VEC3");
  const float s = float(std::sin(kPi / 4)), c = float(std::cos(kPi / 4));
  const int turns = b.add_floats({0, 0, 0, 1, 0, s, 0, c}, "VEC4");
  b.push("animations", {{"samplers",
                         {{{"input", times}, {"output", moves}},
                          {{"input", times}, {"output", turns}, {"interpolation", "LINEAR"}}}},
                        {"channels",
                         {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}},
                          {{"sampler", 1}, {"target", {{"node", 1}, {"path", "rotation"}}}}}}});
  const int step_times = b.add_floats({0.f, 0.5f}, "SCALAR");
  const int scales = b.add_floats({1, 1, 1, 3, 3, 3}, "VEC3");
  b.push("animations",
         {{"samplers", {{{"input", step_times}, {"output", scales}, {"interpolation", "STEP"}}}},
          {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "scale"}}}}}}});
  return b;
}

Scene load_at(const std::string& glb, std::optional<int64_t> frame) {
  TempDir dir;
  return load_scene(dir.write("m.glb", glb), {}, SceneImages::kKeep, {}, {}, frame);
}

float min_x(const Scene& scene) {
  float x = 1e30f;
  for (const Vec3& p : scene.meshes.at(0).positions) x = std::min(x, p.x);
  return x;
}
float max_x(const Scene& scene) {
  float x = -1e30f;
  for (const Vec3& p : scene.meshes.at(0).positions) x = std::max(x, p.x);
  return x;
}

TEST(GltfAnimation, NodesArePosedAtTheFramesTime) {
  const std::string glb = animated().glb();
  const Scene first = load_at(glb, std::nullopt);  // an animated file renders its first frame
  ASSERT_TRUE(first.animation.has_value());
  EXPECT_EQ(first.animation->first, 1);
  EXPECT_EQ(first.animation->last, 25);  // one second at 24 frames a second
  EXPECT_EQ(first.frame, 1);
  EXPECT_NEAR(min_x(first), 0.f, 1e-6);
  EXPECT_NEAR(max_x(first), 1.f, 1e-6);

  const Scene quarter = load_at(glb, 7);  // t = 0.25: moved by 0.5, not scaled yet
  EXPECT_NEAR(min_x(quarter), 0.5f, 1e-6);
  EXPECT_NEAR(max_x(quarter), 1.5f, 1e-6);

  const Scene half = load_at(glb, 13);  // t = 0.5: moved by 1, scaled by 3 (STEP)
  EXPECT_NEAR(min_x(half), 1.f, 1e-5);
  EXPECT_NEAR(max_x(half), 4.f, 1e-5);
  // The camera turned half way, 45 degrees about +y (spherical interpolation).
  const Vec3 d = normalize(half.camera.look_at - half.camera.eye);
  EXPECT_NEAR(d.x, -std::sin(kPi / 4), 1e-5);
  EXPECT_NEAR(d.y, 0.0, 1e-5);
  EXPECT_NEAR(d.z, -std::cos(kPi / 4), 1e-5);

  const Scene last = load_at(glb, 25);
  EXPECT_NEAR(min_x(last), 2.f, 1e-5);
  const Vec3 e = normalize(last.camera.look_at - last.camera.eye);
  EXPECT_NEAR(e.x, -1.0, 1e-5);

  try {
    (void)load_at(glb, 26);
    ADD_FAILURE() << "frame 26 loaded";
  } catch (const SceneError& err) {
    EXPECT_NE(std::string(err.what()).find("frame 26 is outside the scene's frames 1-25"),
              std::string::npos)
        << err.what();
  }
}

TEST(GltfAnimation, CubicSplinesFollowTheirTangents) {
  GltfBuilder b = animated();
  // Node 0's translation instead as a cubic spline with flat tangents: it eases in and out.
  const int times = b.add_floats({0.f, 1.f}, "SCALAR");
  const int keys = b.add_floats({0, 0, 0, 0, 0, 0, 0, 0, 0,   // in, value, out of key 0
                                 0, 0, 0, 4, 0, 0, 0, 0, 0},  // ... of key 1
                                "VEC3");
  b.doc["animations"][0]["samplers"][0] = {
      {"input", times}, {"output", keys}, {"interpolation", "CUBICSPLINE"}};
  const std::string glb = b.glb();
  // t = 0.25: 4 (3 s^2 - 2 s^3) = 0.625; t = 0.5: 2.
  EXPECT_NEAR(min_x(load_at(glb, 7)), 0.625f, 1e-5);
  EXPECT_NEAR(min_x(load_at(glb, 13)), 2.f, 1e-5);
}

TEST(GltfAnimation, TheLastFrameOfAKeyTimeThatFloatRoundsUpIsTheLastKey) {
  // 1/3 s in float is a little above the time of frame 9 (8/24 s) in double: frame 9 is the last
  // frame, inside the last segment by a hair, and must read that segment, not one past it.
  GltfBuilder b = animated();
  const int times = b.add_floats({0.f, float(1.0 / 3.0)}, "SCALAR");
  const int moves = b.add_floats({0, 0, 0, 3, 0, 0}, "VEC3");
  b.doc["animations"][0]["samplers"][0] = {{"input", times}, {"output", moves}};
  b.doc["animations"][0]["samplers"][1]["input"] = times;
  b.doc["animations"][1]["samplers"][0]["input"] = times;
  const std::string glb = b.glb();
  const Scene last = load_at(glb, 9);
  EXPECT_EQ(last.animation->last, 9);
  EXPECT_NEAR(min_x(last), 3.f, 1e-4);
  EXPECT_NEAR(min_x(load_at(glb, 5)), 1.5f, 1e-4);  // 4/24 s: half way
}

// A still JSON scene may pose the file at a time of its choosing (the wrapper `submit --camera`
// sends poses a file whose animations have no length at time 0, as the direct render does).
TEST(GltfAnimation, AStillJsonScenePosesTheFileAtItsTime) {
  TempDir dir;
  dir.write("m.glb", animated().glb());
  const auto at = [&](const std::string& gltf) {
    return load_scene(
        dir.write("s.json", R"({"gltf": )" + gltf + R"(, "film": {"width": 8, "height": 8}})"));
  };
  const Scene posed = at(R"({"file": "m.glb", "time": 0.5})");
  EXPECT_NEAR(min_x(posed), 1.f, 1e-5);
  EXPECT_NEAR(max_x(posed), 4.f, 1e-5);
  EXPECT_FALSE(posed.animation.has_value());
  const Scene as_written = at(R"({"file": "m.glb"})");
  EXPECT_NEAR(min_x(as_written), 0.f, 1e-6);
  try {
    (void)load_scene(dir.write("a.json", R"({"animation": {"frames": [1, 5]},
      "gltf": {"file": "m.glb", "time": 0.5}, "film": {"width": 8, "height": 8}})"));
    ADD_FAILURE() << "a time in an animated scene was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("/gltf/time"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)at(R"({"file": "m.glb", "time": -1})"), SceneError);
}

TEST(GltfAnimation, AJsonSceneNamingAnAnimatedFilePlaysItOverItsOwnFrames) {
  TempDir dir;
  dir.write("m.glb", animated().glb());
  const auto scene = dir.write("scene.json", R"({
    "animation": {"frames": [10, 40], "fps": 12},
    "gltf": {"file": "m.glb"},
    "film": {"width": 8, "height": 8}
  })");
  // Frame 16 of 12 a second from frame 10: t = 0.5.
  const Scene at = load_scene(scene, {}, SceneImages::kKeep, {}, {}, 16);
  EXPECT_NEAR(min_x(at), 1.f, 1e-5);
  EXPECT_NEAR(max_x(at), 4.f, 1e-5);
}

TEST(GltfAnimation, MalformedAnimationsNameTheirPlace) {
  const auto expect_error = [](const GltfBuilder& b, const std::string& words) {
    try {
      (void)load_at(b.glb(), 2);
      ADD_FAILURE() << "expected a SceneError with " << words;
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  GltfBuilder backwards = animated();
  backwards.doc["animations"][0]["samplers"][0]["input"] =
      backwards.add_floats({1.f, 0.f}, "SCALAR");
  expect_error(backwards, "animations[0]/samplers/0/input");
  GltfBuilder short_output = animated();
  short_output.doc["animations"][0]["samplers"][0]["output"] =
      short_output.add_floats({0, 0, 0}, "VEC3");
  expect_error(short_output, "1 values for 2 keys");
  GltfBuilder matrix = animated();
  matrix.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  expect_error(matrix, "must not have a matrix");
  GltfBuilder interpolation = animated();
  interpolation.doc["animations"][1]["samplers"][0]["interpolation"] = "BOUNCE";
  expect_error(interpolation, "unknown interpolation");
  GltfBuilder missing_node = animated();
  missing_node.doc["animations"][1]["channels"][0]["target"]["node"] = 9;
  expect_error(missing_node, "animations[1]/channels/0/target/node");
  // A file without animations is a still: asking for a frame is an error.
  GltfBuilder still = animated();
  still.doc.erase("animations");
  expect_error(still, "the scene is a still");
}

}  // namespace
}  // namespace rayfarm
