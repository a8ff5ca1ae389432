#include "common/scene/gltf_scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "common/limits.h"
#include "common/math/wide.h"
#include "common/scene/animation.h"
#include "common/scene/gltf_loader.h"
#include "common/scene/instances.h"

namespace rayfarm {
namespace fs = std::filesystem;

FilmSize default_gltf_film(double aspect) {
  if (!(aspect > 0.0)) aspect = 16.0 / 9.0;
  aspect = std::clamp(aspect, 1.0 / 16.0, 16.0);
  const auto width = static_cast<uint32_t>(std::max(1.0, std::round(540.0 * aspect)));
  return {width, 540};
}

namespace {

/// A camera for a glTF file that has none: looking down -z at the middle of its meshes' bounds,
/// from far enough that they fit the view.
Camera default_camera(const Scene& scene) {
  WideVec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  extend_bounds(scene, lo, hi);
  Camera c;
  if (!(lo.x <= hi.x)) return c;  // no meshes: whatever lights there are, seen from the origin
  const WideVec3 mid{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2};
  const double radius = std::max(length(hi - lo) / 2, 1e-6);
  const double distance = radius / std::sin(c.fov_y_deg * 3.14159265358979323846 / 360.0);
  c.eye = Vec3(float(mid.x), float(mid.y), float(std::min(mid.z + distance, kMaxCoordinate)));
  c.look_at = Vec3(float(mid.x), float(mid.y), float(mid.z));
  if (c.eye == c.look_at) c.look_at.z -= 1.f;
  return c;
}

}  // namespace

namespace {

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
  if (!result.has_camera) {
    scene.camera = default_camera(scene);
    scene.default_camera = true;
    scene.warnings.push_back(file.string() + kDefaultGltfCameraWarning);
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
