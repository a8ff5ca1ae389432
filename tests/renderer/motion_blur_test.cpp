// Motion blur (common/scene/motion.h): a shape or camera moving within the shutter renders as
// the average of its positions over the shutter's time, against the exact fraction of time and
// area each pixel is covered; the image stays a function of (seed, pixel, sample) alone; and a
// shutter over which nothing moves changes no bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <string>

#include "common/scene/motion.h"
#include "mc_stats.h"
#include "test_scenes.h"
#include "renderer/renderer.h"
#include "renderer/scene_data.h"

namespace rayfarm {
namespace {

// ---- a black shape sliding across a white background, seen by an orthographic camera --------
// The film is 16x4 pixels over x in [-2, 2], y in [-0.5, 0.5]; a pixel's value is the fraction
// of the shutter's time and of its area in which it sees the background.

constexpr uint32_t kWidth = 16, kHeight = 4;
constexpr double kPixel = 0.25;  // scene units per pixel

enum class Mover { kMesh, kInstance, kSphere, kCamera };

// Left edge of the shape (relative to the camera) at `offset` frames after frame 1.
double left_edge(double offset) { return -1.5 + 1.0 * offset; }

Scene sliding_scene(Mover mover, double offset) {
  Scene s;
  s.animation = FrameRange{1, 10, 24.0};
  s.frame = 1;
  s.film = {kWidth, kHeight};
  s.camera.projection = Camera::Projection::kOrthographic;
  s.camera.view_height = 1.f;
  s.camera.eye = {0.f, 0.f, 5.f};
  s.camera.look_at = {0.f, 0.f, 0.f};
  s.background = Vec3(1.f);
  s.render.max_depth = 0;  // the camera ray alone: the background or black
  s.render.sampler = SamplerType::kIndependent;
  Material black;
  black.kind = DiffuseMaterial{Vec3(0.f)};
  s.materials.push_back(black);
  const float a = static_cast<float>(mover == Mover::kCamera ? -0.5 : left_edge(offset));
  TriangleMesh quad;
  quad.positions = {{0, -10, 0}, {1, -10, 0}, {1, 10, 0}, {0, 10, 0}};
  quad.indices = {0, 1, 2, 0, 2, 3};
  quad.materials = {0, 0};
  quad.origin = "quad";
  switch (mover) {
    case Mover::kMesh:
    case Mover::kCamera:
      for (Vec3& p : quad.positions) p.x += a;
      s.meshes.push_back(quad);
      break;
    case Mover::kInstance:
      s.groups.push_back({"slider", {quad}});
      s.instances.push_back({0, {1, 0, 0, a, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}});
      break;
    case Mover::kSphere:
      s.spheres.push_back({Vec3(a + 0.5f, 0.f, 0.f), 0.5f, 0});
      break;
  }
  if (mover == Mover::kCamera) {
    // The camera slides the other way: the quad's left edge relative to it is left_edge().
    const float c = static_cast<float>(-0.5 - left_edge(offset));
    s.camera.eye.x = c;
    s.camera.look_at.x = c;
  }
  return s;
}

// The shape's coverage of pixel (x, y) at left edge `a` (relative to the camera): exact for
// the quads, by a 32x32 grid of points for the sphere's disk.
double coverage(Mover mover, uint32_t x, uint32_t y, double a) {
  const double x0 = -2.0 + x * kPixel, x1 = x0 + kPixel;
  if (mover != Mover::kSphere)
    return std::max(0.0, std::min(x1, a + 1.0) - std::max(x0, a)) / kPixel;
  const double y0 = 0.5 - (y + 1) * kPixel;  // row 0 is the top
  int inside = 0;
  constexpr int kGrid = 32;
  for (int i = 0; i < kGrid; ++i)
    for (int j = 0; j < kGrid; ++j) {
      const double px = x0 + (i + 0.5) * kPixel / kGrid - (a + 0.5);
      const double py = y0 + (j + 0.5) * kPixel / kGrid;
      inside += px * px + py * py < 0.25;
    }
  return double(inside) / (kGrid * kGrid);
}

// Expected pixel value over the shutter [open, close]: 1 - coverage averaged over time.
double expected(Mover mover, uint32_t x, uint32_t y, double open, double close) {
  constexpr int kSteps = 2048;
  double sum = 0.0;
  for (int k = 0; k < kSteps; ++k)
    sum += coverage(mover, x, y, left_edge(open + (close - open) * (k + 0.5) / kSteps));
  return 1.0 - sum / kSteps;
}

Scene with_motion(Mover mover, const RenderSettings& settings) {
  Scene scene = sliding_scene(mover, 0.0);
  scene.motion =
      find_motion(scene, settings, [mover](double o) { return sliding_scene(mover, o); });
  return scene;
}

const char* name(Mover m) {
  switch (m) {
    case Mover::kMesh:
      return "mesh";
    case Mover::kInstance:
      return "instance";
    case Mover::kSphere:
      return "sphere";
    case Mover::kCamera:
      return "camera";
  }
  return "?";
}

// Every pixel's mean against the exact expectation, with the binomial standard error of 4096
// independent samples of 0 or 1; Bonferroni over every pixel of the four movers (1e-3 overall).
TEST(MotionBlur, MovingShapesAndCamerasAverageOverTheShutter) {
  const Mover movers[] = {Mover::kMesh, Mover::kInstance, Mover::kSphere, Mover::kCamera};
  constexpr uint32_t kSpp = 4096;
  const double z_max = testing::bonferroni_z(std::size(movers) * kWidth * kHeight);
  for (Mover mover : movers) {
    RenderSettings settings = sliding_scene(mover, 0.0).render;
    settings.spp = kSpp;
    settings.shutter_open = 0.f;
    settings.shutter_close = 1.5f;
    settings.motion_steps = mover == Mover::kSphere ? 4 : 2;  // linear motion: any count is exact
    const Scene scene = with_motion(mover, settings);
    ASSERT_NE(scene.motion, nullptr);
    ASSERT_TRUE(scene.motion->moves()) << name(mover);
    const Renderer renderer(scene, settings);
    const TileResult r = renderer.render({0, 0, kWidth, kHeight}, {0, kSpp});
    double blurred = 0.0;  // pixels neither always covered nor never
    for (uint32_t y = 0; y < kHeight; ++y) {
      for (uint32_t x = 0; x < kWidth; ++x) {
        const double p = expected(mover, x, y, 0.0, 1.5);
        const double mean = from_fixed(r.sum[(y * kWidth + x) * 3]) / kSpp;
        // A floor of one sample's worth where the expectation is 0 or 1 (or nearly).
        const double se = std::sqrt(std::max(p * (1 - p), 1.0 / kSpp) / kSpp);
        EXPECT_LT(std::fabs(mean - p) / se, z_max)
            << name(mover) << " pixel (" << x << ", " << y << "): " << mean << " expected " << p;
        blurred += p > 0.05 && p < 0.95;
      }
    }
    EXPECT_GE(blurred, 6.0 * (mover == Mover::kSphere ? 1 : kHeight)) << name(mover);
  }
}

// Without the shutter, the same scene is sharp: a pixel is covered or not (no value between).
TEST(MotionBlur, AClosedShutterRendersTheFrameSharp) {
  const Scene scene = sliding_scene(Mover::kMesh, 0.0);  // left edge at -1.5: pixels 2 to 5
  RenderSettings settings = scene.render;
  settings.spp = 64;
  const TileResult r = Renderer(scene, settings).render({0, 0, kWidth, kHeight}, {0, 64});
  for (uint32_t x = 0; x < kWidth; ++x) {
    const double mean = from_fixed(r.sum[x * 3]) / 64;
    EXPECT_EQ(mean, x >= 2 && x < 6 ? 0.0 : 1.0) << "pixel " << x;
  }
}

// A floor lit by a slanted directional light under a black strip sliding above it: a pixel is
// lit while neither its camera ray nor its shadow ray (which crosses the strip's height one unit
// further along +x) meets the strip, at the sample's time. Light sampling's shadow rays must
// look at the strip where it is at that time.
Scene shadowed_floor(double offset) {
  Scene s = sliding_scene(Mover::kMesh, offset);  // the black strip, made 0.5 wide and raised
  TriangleMesh& strip = s.meshes[0];
  for (Vec3& p : strip.positions) {
    p.x = p.x > static_cast<float>(left_edge(offset)) + 0.5f ? p.x - 0.5f : p.x;
    p.z = 1.f;
  }
  Material white;
  white.kind = DiffuseMaterial{Vec3(1.f)};
  s.materials.push_back(white);
  TriangleMesh floor;
  floor.positions = {{-10, -10, 0}, {10, -10, 0}, {10, 10, 0}, {-10, 10, 0}};
  floor.indices = {0, 1, 2, 0, 2, 3};
  floor.materials = {1, 1};
  floor.origin = "floor";
  s.meshes.push_back(floor);
  s.background = Vec3(0.f);
  // Travelling towards -x and -z at 45 degrees; irradiance pi: a lit floor point reads cos 45.
  s.directional_lights.push_back({normalize(Vec3(-1.f, 0.f, -1.f)), Vec3(kPi)});
  s.render.max_depth = 1;
  s.render.integrator = IntegratorType::kNee;
  return s;
}

TEST(MotionBlur, ShadowRaysSeeTheOccluderAtTheSamplesTime) {
  constexpr uint32_t kSpp = 4096;
  RenderSettings settings = shadowed_floor(0.0).render;
  settings.spp = kSpp;
  settings.shutter_open = 0.f;
  settings.shutter_close = 1.5f;
  settings.motion_steps = 2;
  Scene scene = shadowed_floor(0.0);
  scene.motion = find_motion(scene, settings, shadowed_floor);
  ASSERT_EQ(scene.motion->meshes.size(), 1u);  // the strip; the floor keeps still
  const TileResult r = Renderer(scene, settings).render({0, 0, kWidth, kHeight}, {0, kSpp});
  const double lit = std::sqrt(0.5);
  const double z_max = testing::bonferroni_z(kWidth);
  size_t shaded = 0;
  for (uint32_t x = 0; x < kWidth; ++x) {
    // The fraction of (time, position in the pixel) at which both rays pass the strip.
    constexpr int kSteps = 512;
    double clear = 0.0;
    for (int k = 0; k < kSteps; ++k) {
      const double a = left_edge(1.5 * (k + 0.5) / kSteps);
      for (int j = 0; j < kSteps / 8; ++j) {
        const double px = -2.0 + (x + (j + 0.5) / (kSteps / 8)) * kPixel;
        const auto blocked = [a](double at) { return at > a && at < a + 0.5; };
        clear += !blocked(px) && !blocked(px + 1.0);
      }
    }
    const double p = clear / (double(kSteps) * (kSteps / 8));
    const double mean = from_fixed(r.sum[x * 3]) / kSpp / lit;  // row 0; every row is alike
    const double se = std::sqrt(std::max(p * (1 - p), 1.0 / kSpp) / kSpp);
    EXPECT_LT(std::fabs(mean - p) / se, z_max) << "pixel " << x << ": " << mean << " vs " << p;
    shaded += p < 0.95;
  }
  EXPECT_GE(shaded, 8u);
}

// Where Embree finds a moving shape at a ray's time, the hit point the renderer shades is on
// the ray: world meshes, spheres and placements (one placed after a flattened emissive one) are
// posed at the ray's time, not the frame's.
TEST(MotionBlur, HitsAreShadedWhereTheShapeIsAtTheRaysTime) {
  const auto posed = [](double offset) {
    Scene s;
    s.animation = FrameRange{1, 10, 24.0};
    s.frame = 1;
    s.film = {8, 8};
    Material grey, lamp;
    lamp.emission = Vec3(1.f);
    s.materials = {grey, lamp};
    TriangleMesh quad;
    quad.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    quad.indices = {0, 1, 2, 0, 2, 3};
    quad.materials = {0, 0};
    quad.origin = "quad";
    TriangleMesh lamp_quad = quad;
    lamp_quad.materials = {1, 1};
    s.groups.push_back({"lamp", {lamp_quad}});
    s.groups.push_back({"box", {quad}});
    const double o = offset;
    // A lamp placed first (flattened into the world), then the box turning and sliding.
    s.instances.push_back({0, {1, 0, 0, 5, 0, 1, 0, 5, 0, 0, 1, 0, 0, 0, 0, 1}});
    const double c = std::cos(0.5 * o), sn = std::sin(0.5 * o);
    s.instances.push_back({1, {c, -sn, 0, -3 + o, sn, c, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}});
    TriangleMesh slider = quad;
    for (Vec3& p : slider.positions) p = p + Vec3(0.f, static_cast<float>(-3 + o), 0.f);
    s.meshes.push_back(slider);
    s.spheres.push_back({Vec3(static_cast<float>(2 + o), 0.f, 0.f), 0.5f, 0});
    return s;
  };
  Scene scene = posed(0.0);
  RenderSettings settings;
  settings.shutter_close = 2.f;
  settings.motion_steps = 3;
  scene.motion = find_motion(scene, settings, posed);
  ASSERT_EQ(scene.motion->instances.size(), 1u);
  EXPECT_EQ(scene.motion->instances[0].instance, 1u);
  const SceneData data(scene);
  ASSERT_EQ(data.instances(), 1u);
  ASSERT_EQ(data.flattened_instances(), 1u);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  int hits[3] = {0, 0, 0};  // mesh, sphere, instance
  for (int i = 0; i < 20000; ++i) {
    Ray ray;
    ray.org = Vec3(-4.f + 8.f * unit(rng), -4.f + 8.f * unit(rng), 5.f);
    ray.dir = Vec3(0.f, 0.f, -1.f);
    ray.time = unit(rng);
    const std::optional<RayHit> hit = data.bvh().intersect(ray);
    if (!hit) continue;
    const SurfaceHit s = data.resolve(ray, *hit);
    const Vec3 on_ray = ray.org + ray.dir * hit->t;
    ASSERT_LT(length(s.p - on_ray), 1e-4f)
        << "geom " << hit->geom << " inst " << hit->inst << " at time " << ray.time;
    ++hits[hit->geom == kSphereGeometry ? 1 : hit->inst != kNoInstance ? 2 : 0];
  }
  for (int h : hits) EXPECT_GT(h, 100);
}

// ---- the contract: (seed, pixel, sample) alone decide the image --------------------------------

// The small room with its mirror sphere rising, its camera sliding and a placed prism turning.
Scene moving_room(double offset) {
  Scene s = testing::small_room_scene();
  s.animation = FrameRange{1, 10, 24.0};
  s.frame = 1;
  s.spheres[0].center.y += static_cast<float>(0.3 * offset);
  s.camera.eye.x += static_cast<float>(0.2 * offset);
  TriangleMesh prism;
  prism.positions = {{0, 0, 0}, {0.3f, 0, 0}, {0.3f, 0.3f, 0}, {0, 0.3f, 0.3f}};
  prism.indices = {0, 1, 2, 0, 2, 3, 0, 3, 1};
  prism.materials = {2, 2, 2};
  s.groups.push_back({"prism", {prism}});
  const double t = 0.4 * offset, c = std::cos(t), sn = std::sin(t);
  s.instances.push_back({0, {c, 0, sn, -0.2, 0, 1, 0, 0.3, -sn, 0, c, -0.3, 0, 0, 0, 1}});
  return s;
}

TEST(MotionBlur, ThreadsTilesAndPassesDoNotChangeABlurredImage) {
  for (SamplerType sampler : {SamplerType::kSobol, SamplerType::kIndependent}) {
    Scene scene = moving_room(0.0);
    RenderSettings settings = scene.render;
    settings.spp = 8;
    settings.seed = 7;
    settings.sampler = sampler;
    settings.shutter_open = -0.5f;
    settings.shutter_close = 0.5f;
    settings.motion_steps = 3;
    scene.motion = find_motion(scene, settings, moving_room);
    ASSERT_TRUE(scene.motion->moves());
    EXPECT_EQ(scene.motion->spheres.size(), 1u);
    EXPECT_EQ(scene.motion->instances.size(), 1u);
    EXPECT_EQ(scene.motion->cameras.size(), 3u);
    const Renderer renderer(scene, settings);
    EXPECT_NE(renderer.plan().find("shutter [-0.5, 0.5] frames, 3 poses: 0 meshes, 1 spheres, "
                                   "1 placements and the camera move"),
              std::string::npos)
        << renderer.plan();
    const Film a = testing::render_with(renderer, 1, 64, 8);
    const Film b = testing::render_with(renderer, 2, 7, 3);
    EXPECT_TRUE(a.sum() == b.sum()) << sampler_name(sampler);
    EXPECT_TRUE(a.sum_sq() == b.sum_sq()) << sampler_name(sampler);
    // And the blur is there: the closed shutter's image differs.
    RenderSettings closed = settings;
    closed.shutter_close = closed.shutter_open;
    const Film sharp = testing::render_with(Renderer(moving_room(0.0), closed), 2, 16, 8);
    EXPECT_FALSE(a.sum() == sharp.sum()) << sampler_name(sampler);
  }
}

// An open shutter over which nothing moves (a still scene, or an animated one whose shapes and
// camera keep still) draws no time: every bit is the closed shutter's.
TEST(MotionBlur, NothingMovingChangesNoBit) {
  Scene animated = testing::small_room_scene();
  animated.animation = FrameRange{1, 10, 24.0};
  animated.frame = 1;
  RenderSettings closed = animated.render;
  closed.spp = 8;
  RenderSettings open = closed;
  open.shutter_open = 0.f;
  open.shutter_close = 1.f;
  animated.motion = find_motion(animated, open, [&](double) { return animated; });
  ASSERT_NE(animated.motion, nullptr);
  EXPECT_FALSE(animated.motion->moves());
  const Film sharp = testing::render_with(Renderer(testing::small_room_scene(), closed), 2, 16, 8);
  const Film same = testing::render_with(Renderer(animated, open), 2, 16, 8);
  EXPECT_TRUE(sharp.sum() == same.sum());
  const Film still = testing::render_with(Renderer(testing::small_room_scene(), open), 2, 16, 8);
  EXPECT_TRUE(sharp.sum() == still.sum());
}

// A renderer given an animated scene with an open shutter but no motion found refuses it,
// rather than render the frame unblurred.
TEST(MotionBlur, ARendererRefusesAShutterWhoseMotionWasNotFound) {
  Scene scene = sliding_scene(Mover::kMesh, 0.0);
  RenderSettings settings = scene.render;
  settings.shutter_close = 1.f;
  EXPECT_THROW(Renderer(scene, settings), std::runtime_error);
  scene = with_motion(Mover::kMesh, settings);
  RenderSettings other = settings;
  other.shutter_close = 0.5f;  // found for another shutter
  EXPECT_THROW(Renderer(scene, other), std::runtime_error);
  EXPECT_NO_THROW(Renderer(scene, settings));
}

// An emitter that moves is drawn where the frame puts it: light sampling and hits agree.
TEST(MotionBlur, MovingEmittersStayAtTheFrame) {
  const auto lamp_at = [](double offset) {
    Scene s = sliding_scene(Mover::kMesh, offset);
    s.materials[0].emission = Vec3(2.f);
    return s;
  };
  Scene scene = lamp_at(0.0);
  RenderSettings settings = scene.render;
  settings.spp = 16;
  settings.shutter_close = 1.f;
  scene.motion = find_motion(scene, settings, lamp_at);
  ASSERT_NE(scene.motion, nullptr);
  EXPECT_FALSE(scene.motion->moves());
  ASSERT_EQ(scene.motion->still.size(), 1u);
  const TileResult r = Renderer(scene, settings).render({0, 0, kWidth, kHeight}, {0, 16});
  for (uint32_t x = 0; x < kWidth; ++x)
    EXPECT_EQ(from_fixed(r.sum[x * 3]) / 16, x >= 2 && x < 6 ? 2.0 : 1.0) << "pixel " << x;
}

}  // namespace
}  // namespace rayfarm
