#include "common/scene/gltf_scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "common/limits.h"
#include "common/math/wide.h"
#include "common/scene/animation.h"
#include "common/scene/gltf_loader.h"
#include "common/scene/instances.h"
#include "common/scene/json_reader.h"
#include "common/scene/light_reader.h"

namespace rayfarm {
namespace fs = std::filesystem;

FilmSize default_gltf_film(double aspect) {
  if (!(aspect > 0.0)) aspect = 16.0 / 9.0;
  aspect = std::clamp(aspect, 1.0 / 16.0, 16.0);
  const auto width = static_cast<uint32_t>(std::max(1.0, std::round(540.0 * aspect)));
  return {width, 540};
}

Camera default_view(const Scene& scene) {
  WideVec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  extend_bounds(scene, lo, hi);  // meshes, spheres and placed groups
  Camera c;
  if (!(lo.x <= hi.x)) return c;  // no shapes: whatever lights there are, seen from the origin
  const WideVec3 mid{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2};
  const double radius = std::max(length(hi - lo) / 2, 1e-6);
  const double distance = radius / std::sin(c.fov_y_deg * 3.14159265358979323846 / 360.0);
  // From the front (+z), 30 degrees to the right and 25 degrees above: a flat model lying in any
  // of the three axis planes is seen at an angle, never edge-on.
  const double to_rad = 3.14159265358979323846 / 180.0;
  const double azimuth = 30.0 * to_rad, elevation = 25.0 * to_rad;
  const WideVec3 dir{std::sin(azimuth) * std::cos(elevation), std::sin(elevation),
                     std::cos(azimuth) * std::cos(elevation)};
  auto coordinate = [](double v) {
    return float(std::clamp(v, -double(kMaxCoordinate), double(kMaxCoordinate)));
  };
  c.eye = Vec3(coordinate(mid.x + distance * dir.x), coordinate(mid.y + distance * dir.y),
               coordinate(mid.z + distance * dir.z));
  c.look_at = Vec3(float(mid.x), float(mid.y), float(mid.z));
  if (c.eye == c.look_at) c.look_at.z -= 1.f;
  return c;
}

namespace {

/// GltfOptions::environment as the JSON scene's light that says the same, read as one.
void add_environment(const fs::path& file, const std::string& environment, SceneImages images,
                     Scene& scene) {
  using scene_json::Json;
  const Json lights = environment == "uniform"
                          ? Json::array({{{"type", "constant"}, {"radiance", {1, 1, 1}}}})
                          : Json::array({{{"type", "environment"}, {"file", environment}}});
  const scene_json::Context context{file.string() + " --environment", &scene.warnings};
  const TextureReader no_textures(file.parent_path(), images);
  read_lights(scene_json::Node(lights, context, ""), file.parent_path(), images, no_textures,
              scene);
}

Scene load_gltf_frame(const fs::path& file, const SceneCheck& check, SceneImages images,
                      GltfOptions options, std::optional<int64_t> frame, double frame_offset) {
  Scene scene;
  scene.source = file;
  // An animated file is a sequence of frames at kGltfFps from time 0 (frame 1) to its last key.
  if (frame && (*frame < -kMaxFrameNumber || *frame > kMaxFrameNumber)) {
    throw SceneError(file.string() + ": frame " + std::to_string(*frame) +
                     " is out of range (frame numbers are within +-1000000000)");
  }
  options.time = (double(frame.value_or(1) - 1) + frame_offset) / kGltfFps;
  const GltfResult result = load_gltf(file.parent_path(), file.filename(), options, images, scene);
  if (result.duration > 0.0) {
    const double frames =
        std::min(std::ceil(result.duration * kGltfFps - 1e-6), double(kMaxFrameNumber - 1));
    scene.animation = FrameRange{1, 1 + int64_t(frames), kGltfFps};
    scene.frame = frame.value_or(1);
  }
  check_frame(file.string(), scene.animation, frame);
  scene.film = default_gltf_film(result.aspect);
  if (check) {
    if (auto refusal = check(scene.film, scene.render)) throw SceneRefused(*refusal);
  }
  if (!options.environment.empty()) add_environment(file, options.environment, images, scene);
  if (!result.has_camera) {
    scene.camera = default_view(scene);
    scene.default_camera = true;
    scene.warnings.push_back(file.string() + ": the file has no camera" + kDefaultViewWarning);
  }
  return scene;
}

}  // namespace

Scene load_gltf_scene(const fs::path& file, const SceneCheck& check, SceneImages images,
                      GltfOptions options, std::optional<int64_t> frame, double frame_offset) {
  if (frame_offset == 0.0)
    return load_gltf_frame(file, check, images, std::move(options), frame, 0.0);
  try {
    return load_gltf_frame(file, check, images, std::move(options), frame, frame_offset);
  } catch (const SceneRefused&) {
    throw;
  } catch (const SceneError& e) {  // a pose within the shutter: say which
    throw SceneError(
        fmt::format("frame {} {:+g} of {}", frame.value_or(1), frame_offset, e.what()));
  }
}

}  // namespace rayfarm
