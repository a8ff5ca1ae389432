// Motion blur's poses (common/scene/motion.h): an animated scene posed within an open shutter,
// JSON keyframes and glTF animations alike; what moves and what stays still (emitters, shapes of
// groups); the shutter's settings and their refusals.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "tests/support/gltf_builder.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

using testing::TempDir;

// A quad sliding along +x by one unit a frame, a sphere rising, an emitting quad sliding too, and
// a still floor; the camera turns its look-at.
constexpr const char* kSliding = R"({
  "animation": {"frames": [1, 10]},
  "camera": {"eye": [0, 0, 5], "look_at": {"keyframes": [[1, [0, 0, 0]], [10, [9, 0, 0]]]},
             "fov_y": 40},
  "film": {"width": 8, "height": 8},
  "materials": {"grey": {"type": "diffuse"},
                "lamp": {"type": "diffuse", "emission": [1, 1, 1]}},
  "shapes": [
    {"type": "quad", "corner": [-10, -1, -1], "edge1": [20, 0, 0], "edge2": [0, 0, -5],
     "material": "grey"},
    {"type": "quad", "corner": [0, 0, 0], "edge1": [1, 0, 0], "edge2": [0, 1, 0],
     "material": "grey",
     "transform": [{"translate": {"keyframes": [[1, [0, 0, 0]], [10, [9, 0, 0]]]}}]},
    {"type": "sphere", "center": {"keyframes": [[1, [0, 0, 0]], [10, [0, 9, 0]]]}, "radius": 0.5,
     "material": "grey"},
    {"type": "quad", "corner": [0, 3, 0], "edge1": [1, 0, 0], "edge2": [0, 0, 1],
     "material": "lamp",
     "transform": [{"translate": {"keyframes": [[1, [0, 0, 0]], [10, [9, 0, 0]]]}}]}
  ],
  "render": RENDER
})";

std::string sliding(const std::string& render) {
  std::string s = kSliding;
  s.replace(s.find("RENDER"), 6, render);
  return s;
}

float min_x(const std::vector<Vec3>& positions) {
  float x = 1e30f;
  for (const Vec3& p : positions) x = std::min(x, p.x);
  return x;
}

TEST(Motion, JsonKeyframesArePosedAcrossTheShutter) {
  TempDir dir;
  const auto file = dir.write("s.json", sliding(R"({"shutter": [-0.5, 0.5], "motion_steps": 3})"));
  Scene scene = load_scene(file, {}, SceneImages::kKeep, {}, {}, 4);
  EXPECT_EQ(scene.render.shutter_open, -0.5f);
  EXPECT_EQ(scene.render.shutter_close, 0.5f);
  EXPECT_EQ(scene.render.motion_steps, 3u);
  add_motion(scene, scene.render);
  ASSERT_NE(scene.motion, nullptr);
  const SceneMotion& m = *scene.motion;
  EXPECT_EQ(m.times, (std::vector<double>{-0.5, 0.0, 0.5}));
  // The sliding quad (mesh 1) at frames 3.5, 4 and 4.5: x from 2.5 to 3.5.
  ASSERT_EQ(m.meshes.size(), 1u);
  EXPECT_EQ(m.meshes[0].mesh, 1u);
  ASSERT_EQ(m.meshes[0].positions.size(), 3u);
  EXPECT_FLOAT_EQ(min_x(m.meshes[0].positions[0]), 2.5f);
  EXPECT_FLOAT_EQ(min_x(m.meshes[0].positions[1]), 3.f);
  EXPECT_FLOAT_EQ(min_x(m.meshes[0].positions[2]), 3.5f);
  ASSERT_EQ(m.spheres.size(), 1u);
  EXPECT_FLOAT_EQ(m.spheres[0].poses[0].center.y, 2.5f);
  EXPECT_FLOAT_EQ(m.spheres[0].poses[2].center.y, 3.5f);
  ASSERT_EQ(m.cameras.size(), 3u);
  EXPECT_FLOAT_EQ(m.cameras[0].look_at.x, 2.5f);
  EXPECT_FLOAT_EQ(m.cameras[2].look_at.x, 3.5f);
  EXPECT_TRUE(m.moves());
  // The emitting quad stays where frame 4 puts it, and the scene says so.
  ASSERT_EQ(m.still.size(), 1u);
  EXPECT_NE(m.still[0].find("emits light"), std::string::npos) << m.still[0];
  EXPECT_TRUE(std::any_of(scene.warnings.begin(), scene.warnings.end(), [](const std::string& w) {
    return w.find("motion blur") != std::string::npos;
  }));
}

// A camera (or shape) that first differs from the frame at a later pose keeps the frame's value
// at the poses before: a shutter opening at the frame itself.
TEST(Motion, PosesBeforeTheFirstChangeAreTheFrames) {
  TempDir dir;
  const auto file = dir.write("s.json", sliding(R"({"shutter": [0, 1], "motion_steps": 3})"));
  Scene scene = load_scene(file, {}, SceneImages::kKeep, {}, {}, 4);
  add_motion(scene, scene.render);
  ASSERT_NE(scene.motion, nullptr);
  const SceneMotion& m = *scene.motion;
  ASSERT_EQ(m.cameras.size(), 3u);
  EXPECT_EQ(m.cameras[0].look_at, scene.camera.look_at);
  EXPECT_FLOAT_EQ(m.cameras[2].look_at.x, 4.f);
  ASSERT_EQ(m.meshes.size(), 1u);
  EXPECT_EQ(m.meshes[0].positions[0], scene.meshes[1].positions);
  EXPECT_FLOAT_EQ(min_x(m.meshes[0].positions[1]), 3.5f);
  ASSERT_EQ(m.spheres.size(), 1u);
  EXPECT_EQ(m.spheres[0].poses.size(), 3u);
  EXPECT_EQ(m.spheres[0].poses[0].center, scene.spheres[0].center);
  // The ends alone, as the master checks them at admission.
  EXPECT_NO_THROW(check_shutter_ends(scene, scene.render, [&](double offset) {
    return load_scene_pose(file, {}, {}, scene.frame, offset);
  }));
}

TEST(Motion, AClosedShutterOrAStillSceneHasNoMotion) {
  TempDir dir;
  Scene closed = load_scene(dir.write("c.json", sliding("{}")), {}, SceneImages::kKeep, {}, {}, 4);
  add_motion(closed, closed.render);
  EXPECT_EQ(closed.motion, nullptr);

  const auto still = dir.write("still.json", R"({
    "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "fov_y": 40},
    "film": {"width": 8, "height": 8},
    "materials": {"grey": {"type": "diffuse"}},
    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "grey"}],
    "render": {"shutter": [0, 1]}})");
  Scene s = load_scene(still);
  add_motion(s, s.render);
  EXPECT_EQ(s.motion, nullptr);
}

TEST(Motion, NothingMovingIsSaidSo) {
  TempDir dir;
  // Only a light's intensity is keyframed: the poses agree on every shape and the camera.
  const auto file = dir.write("l.json", R"({
    "animation": {"frames": [1, 10]},
    "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "fov_y": 40},
    "film": {"width": 8, "height": 8},
    "materials": {"grey": {"type": "diffuse"}},
    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "grey"}],
    "lights": [{"type": "point", "position": [0, 3, 3],
                "intensity": {"keyframes": [[1, [1, 1, 1]], [10, [9, 9, 9]]]}}],
    "render": {"shutter": [0, 1]}})");
  Scene s = load_scene(file, {}, SceneImages::kKeep, {}, {}, 2);
  add_motion(s, s.render);
  ASSERT_NE(s.motion, nullptr);
  EXPECT_FALSE(s.motion->moves());
  EXPECT_TRUE(s.motion->still.empty());
  EXPECT_EQ(s.motion->steps(), kDefaultMotionSteps);
}

// A glTF file's animation is sampled at the poses' times: 24 frames a second from frame 1.
TEST(Motion, GltfAnimationsArePosedAcrossTheShutter) {
  testing::GltfBuilder b;
  const int mesh = b.add_quad(-1);
  b.push("nodes", {{"mesh", mesh}});
  b.doc["scenes"] = {{{"nodes", {0}}}};
  b.doc["scene"] = 0;
  const int times = b.add_floats({0.f, 1.f}, "SCALAR");
  const int moves = b.add_floats({0, 0, 0, 24, 0, 0}, "VEC3");  // one unit a frame
  b.push("animations",
         {{"samplers", {{{"input", times}, {"output", moves}}}},
          {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}}});
  TempDir dir;
  const auto glb = dir.write("m.glb", b.glb());
  RenderSettings settings;
  settings.shutter_open = 0.f;
  settings.shutter_close = 0.5f;
  settings.motion_steps = 2;
  Scene direct = load_scene(glb, {}, SceneImages::kKeep, {}, {}, 7);
  add_motion(direct, settings);
  ASSERT_NE(direct.motion, nullptr);
  ASSERT_EQ(direct.motion->meshes.size(), 1u);
  EXPECT_NEAR(min_x(direct.motion->meshes[0].positions[0]), 6.f, 1e-4);
  EXPECT_NEAR(min_x(direct.motion->meshes[0].positions[1]), 6.5f, 1e-4);
  // The file has no camera: the default one, placed from the meshes' bounds at the frame, keeps
  // still instead of chasing the quad.
  EXPECT_TRUE(direct.motion->cameras.empty());

  // Named by a JSON scene with frames of its own (12 a second from frame 10): frame 16 is t = 0.5
  // s.
  const auto scene = dir.write("scene.json", R"({
    "animation": {"frames": [10, 40], "fps": 12},
    "gltf": {"file": "m.glb"},
    "camera": {"eye": [0, 0, 50], "look_at": [0, 0, 0], "fov_y": 40},
    "film": {"width": 8, "height": 8},
    "render": {"shutter": [0, 1], "motion_steps": 2}})");
  Scene named = load_scene(scene, {}, SceneImages::kKeep, {}, {}, 16);
  add_motion(named, named.render);
  ASSERT_NE(named.motion, nullptr);
  ASSERT_EQ(named.motion->meshes.size(), 1u);
  EXPECT_NEAR(min_x(named.motion->meshes[0].positions[0]), 12.f, 1e-3);  // 0.5 s x 24 units/s
  EXPECT_NEAR(min_x(named.motion->meshes[0].positions[1]), 14.f, 1e-3);  // 7/12 s
}

TEST(Motion, APoseWithOtherShapesIsRefused) {
  TempDir dir;
  Scene scene = load_scene(dir.write("s.json", sliding(R"({"shutter": [0, 1]})")), {},
                           SceneImages::kKeep, {}, {}, 2);
  try {
    (void)find_motion(scene, scene.render, [&](double offset) {
      Scene pose = scene;
      if (offset > 0.5) pose.meshes[1].positions.push_back({0, 0, 0});
      return pose;
    });
    ADD_FAILURE() << "a pose with another vertex count was accepted";
  } catch (const SceneError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("changes its vertices or triangles within the shutter"), std::string::npos)
        << what;
    EXPECT_NE(what.find("frame 2 +0.75"), std::string::npos) << what;  // the first such pose
  }
}

TEST(Motion, BadShuttersNameTheirPlace) {
  TempDir dir;
  const auto refused = [&](const std::string& render, const std::string& expected) {
    const auto file = dir.write("bad.json", sliding(render));
    try {
      (void)load_scene(file, {}, SceneImages::kKeep, {}, {}, 2);
      ADD_FAILURE() << render << " was accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  refused(R"({"shutter": [0.5, 0]})", "/render/shutter: the shutter closes (0) before it opens");
  refused(R"({"shutter": [0, 1000]})", "/render/shutter/1: a shutter end must be within +-100");
  refused(R"({"shutter": [0]})", "/render/shutter: expected [OPEN, CLOSE]");
  refused(R"({"shutter": [0, 1], "motion_steps": 1})", "/render/motion_steps");
  refused(R"({"shutter": [0, 1], "motion_steps": 65})", "/render/motion_steps");
  // A keyframed shutter: every frame of a sequence renders with the same settings.
  refused(R"({"shutter": {"keyframes": [[1, [0, 1]], [2, [0, 2]]]}})",
          "\"render\" cannot be keyframed");

  EXPECT_FALSE(shutter_problem(-0.25f, 0.25f, 5).has_value());
  EXPECT_TRUE(shutter_problem(0.25f, -0.25f, 5).has_value());
  EXPECT_TRUE(shutter_problem(0.f, 200.f, 5).has_value());
  EXPECT_TRUE(shutter_problem(0.f, 1.f, 1).has_value());
  EXPECT_TRUE(shutter_problem(std::nanf(""), 1.f, 5).has_value());
}

// The bundled scene: a fan spinning (a placed group), a checkered ball rolling and a glass ball
// bouncing, under a still camera and a still lamp.
TEST(Motion, TheBundledSceneBlursItsFanAndBalls) {
  Scene scene = load_scene(
      std::filesystem::path(RAYFARM_SOURCE_DIR) / "scenes" / "motion-blur" / "scene.json", {},
      SceneImages::kKeep, {}, {}, 12);
  EXPECT_EQ(scene.render.shutter_open, -0.25f);
  EXPECT_EQ(scene.render.shutter_close, 0.25f);
  add_motion(scene, scene.render);
  EXPECT_TRUE(scene.warnings.empty()) << scene.warnings.front();
  ASSERT_NE(scene.motion, nullptr);
  EXPECT_EQ(scene.motion->instances.size(), 1u);
  EXPECT_EQ(scene.motion->spheres.size(), 2u);
  EXPECT_TRUE(scene.motion->meshes.empty());
  EXPECT_TRUE(scene.motion->cameras.empty());
  EXPECT_TRUE(scene.motion->still.empty());
}

}  // namespace
}  // namespace rayfarm
