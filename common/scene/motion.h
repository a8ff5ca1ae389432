#pragma once
// Motion blur (docs/scene-format.md, "Motion blur"): what moves while the shutter is open.
//
// An animated scene rendered with an open shutter is posed at RenderSettings::motion_steps
// times, evenly spaced from the shutter's opening to its closing; between two poses, moving
// shapes and the camera move linearly. A sample's time u in [0, 1) (one more number of the
// sample, path_sampler.h) falls between pose floor(u (K - 1)) and the next. What moves:
//  - the camera (eye, look-at, up, field of view, lens);
//  - world meshes (their vertices and normals) and spheres (centre, radius, axes);
//  - the placements (instances) of mesh groups.
// Everything else keeps the value it has at the frame itself: materials, textures, lights and
// the background. Emitting shapes are drawn where the frame puts them too (light sampling needs
// them in one place), and so are group meshes that change shape (only whole placements move):
// SceneMotion::still lists them, and the scene's warnings say so.
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/scene/gltf_options.h"
#include "common/scene/scene.h"

namespace rayfarm {

struct SceneMotion {
  /// The poses' times after the frame, in frames: the shutter's opening to its closing.
  std::vector<double> times;
  /// The camera at each pose, or empty when it does not move.
  std::vector<Camera> cameras;

  struct MeshPoses {
    uint32_t mesh;                             ///< into Scene::meshes
    std::vector<std::vector<Vec3>> positions;  ///< per pose, as TriangleMesh::positions
    std::vector<std::vector<Vec3>> normals;    ///< per pose, or empty (no vertex normals)
  };
  std::vector<MeshPoses> meshes;  ///< the world meshes that move, by increasing index

  struct SpherePoses {
    uint32_t sphere;            ///< into Scene::spheres
    std::vector<Sphere> poses;  ///< per pose (material as the frame's)
  };
  std::vector<SpherePoses> spheres;  ///< the spheres that move, by increasing index

  struct InstancePoses {
    uint32_t instance;                          ///< into Scene::instances
    std::vector<std::array<double, 16>> poses;  ///< world_from_object per pose
  };
  std::vector<InstancePoses> instances;  ///< the placements that move, by increasing index

  /// What moves within the shutter but is drawn where the frame puts it, with the reason.
  std::vector<std::string> still;

  size_t steps() const { return times.size(); }
  bool moves() const {
    return !cameras.empty() || !meshes.empty() || !spheres.empty() || !instances.empty();
  }
};

/// Why a shutter from `open` to `close` frames after the frame with `steps` poses cannot be
/// rendered (not finite, beyond +-kMaxShutterFrames, closing before it opens, steps outside
/// kMinMotionSteps..kMaxMotionSteps); nullopt when it can.
std::optional<std::string> shutter_problem(float open, float close, uint32_t steps);

/// "OPEN,CLOSE frames, N poses": the EXR attribute rayfarm:shutter of a blurred image.
std::string shutter_attribute(const RenderSettings& settings);

/// The pose of `scene` (loaded at its frame) `offset` frames after that frame.
using PoseLoader = std::function<Scene(double offset)>;

/// What moves in `scene` within the shutter of `settings`, from its poses (load_pose) (moves()
/// false when nothing does). Null when the shutter is closed or the scene is a still. Throws
/// SceneError when
/// a pose's shapes differ from the frame's in number or in their vertices and triangles.
std::shared_ptr<const SceneMotion> find_motion(const Scene& scene, const RenderSettings& settings,
                                               const PoseLoader& load_pose);

/// What the master checks at admission, at the cost of two reads and one pose in memory: the
/// poses at the shutter's opening and closing load, with the frame's shapes. Throws SceneError as
/// find_motion() does; nothing when the shutter is closed or the scene a still.
void check_shutter_ends(const Scene& scene, const RenderSettings& settings,
                        const PoseLoader& load_pose);

/// find_motion() for a scene that load_scene() read from scene.source (with these glTF options
/// and root): sets scene.motion, and adds a warning for each thing that stays still. A Renderer
/// refuses an animated scene with an open shutter whose motion was not found for its settings.
void add_motion(Scene& scene, const RenderSettings& settings, const GltfOptions& gltf = {},
                const std::filesystem::path& root = {});

}  // namespace rayfarm
