#include "common/scene/motion.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "common/scene/gltf_scene.h"
#include "common/scene/instances.h"
#include "common/scene/parser.h"

namespace rayfarm {
namespace {

bool same_pose(const Camera& a, const Camera& b) {
  return a.eye == b.eye && a.look_at == b.look_at && a.up == b.up && a.fov_y_deg == b.fov_y_deg &&
         a.aperture_radius == b.aperture_radius && a.focus_distance == b.focus_distance &&
         a.view_height == b.view_height;
}

bool same_pose(const Sphere& a, const Sphere& b) {
  return a.center == b.center && a.radius == b.radius && a.axis_x == b.axis_x &&
         a.axis_y == b.axis_y && a.axis_z == b.axis_z;
}

bool same_pose(const TriangleMesh& a, const TriangleMesh& b) {
  return a.positions == b.positions && a.normals == b.normals;
}

bool emits(const Scene& scene, const TriangleMesh& mesh) {
  for (uint32_t m : mesh.materials)
    if (scene.materials[m].is_emissive()) return true;
  return false;
}

std::string when(const Scene& scene, double offset) {
  return fmt::format("{}: frame {} {:+g}", scene.source.string(), scene.frame.value_or(0), offset);
}

/// Refuses a pose whose shapes are not the frame's shapes moved: another count, or a mesh with
/// other triangles or another number of vertices (Embree moves vertices, it cannot remesh).
void check_topology(const Scene& frame, const Scene& pose, double offset) {
  const auto refuse = [&](const std::string& what) {
    throw SceneError(when(frame, offset) + ": " + what +
                     " within the shutter; motion blur moves shapes, it cannot change them");
  };
  if (pose.meshes.size() != frame.meshes.size() || pose.spheres.size() != frame.spheres.size() ||
      pose.instances.size() != frame.instances.size() || pose.groups.size() != frame.groups.size())
    refuse(fmt::format(
        "the scene has {} meshes, {} spheres, {} groups and {} instances against "
        "{}, {}, {} and {} at the frame",
        pose.meshes.size(), pose.spheres.size(), pose.groups.size(), pose.instances.size(),
        frame.meshes.size(), frame.spheres.size(), frame.groups.size(), frame.instances.size()));
  const auto same_mesh = [&](const TriangleMesh& a, const TriangleMesh& b) {
    if (a.positions.size() != b.positions.size() || a.normals.size() != b.normals.size() ||
        a.indices.size() != b.indices.size())
      refuse("mesh " + b.origin + " changes its vertices or triangles");
    if (a.indices != b.indices)  // the same count, another order: a mirror turned its corners
      refuse("mesh " + b.origin +
             " changes its triangles (a scale through zero mirrors it, which turns its "
             "triangles' corners)");
  };
  for (size_t i = 0; i < frame.meshes.size(); ++i) same_mesh(pose.meshes[i], frame.meshes[i]);
  for (size_t g = 0; g < frame.groups.size(); ++g) {
    if (pose.groups[g].meshes.size() != frame.groups[g].meshes.size())
      refuse("group \"" + frame.groups[g].name + "\" changes its number of meshes");
    for (size_t i = 0; i < frame.groups[g].meshes.size(); ++i)
      same_mesh(pose.groups[g].meshes[i], frame.groups[g].meshes[i]);
  }
  for (size_t i = 0; i < frame.instances.size(); ++i)
    if (pose.instances[i].group != frame.instances[i].group)
      refuse("instance " + std::to_string(i) + " places another group");
}

}  // namespace

std::optional<std::string> shutter_problem(float open, float close, uint32_t steps) {
  if (!(std::fabs(open) <= kMaxShutterFrames) || !(std::fabs(close) <= kMaxShutterFrames))
    return fmt::format("a shutter [{:g}, {:g}] beyond +-{:g} frames of the frame", open, close,
                       kMaxShutterFrames);
  if (close < open)
    return fmt::format("a shutter that closes ({:g}) before it opens ({:g})", close, open);
  if (steps < kMinMotionSteps || steps > kMaxMotionSteps)
    return fmt::format("{} motion steps (from {} to {})", steps, kMinMotionSteps, kMaxMotionSteps);
  return std::nullopt;
}

std::string shutter_attribute(const RenderSettings& settings) {
  return fmt::format("{:g},{:g} frames, {} poses", settings.shutter_open, settings.shutter_close,
                     settings.motion_steps);
}

std::shared_ptr<const SceneMotion> find_motion(const Scene& scene, const RenderSettings& settings,
                                               const PoseLoader& load_pose) {
  if (!settings.shutter_is_open() || !scene.animation) return nullptr;
  auto motion = std::make_shared<SceneMotion>();
  const uint32_t k = std::clamp(settings.motion_steps, kMinMotionSteps, kMaxMotionSteps);
  // A glTF file's default camera is placed from its meshes' bounds: it would chase them.
  const bool default_camera = scene.default_camera;
  // One pose in memory at a time: what differs from the frame is kept, from the pose where it
  // first differs (the poses before it are the frame's own values).
  std::vector<int32_t> mesh_at(scene.meshes.size(), -1), sphere_at(scene.spheres.size(), -1),
      instance_at(scene.instances.size(), -1);
  std::vector<uint8_t> still_mesh(scene.meshes.size(), 0), still_sphere(scene.spheres.size(), 0),
      still_instance(scene.instances.size(), 0), group_changes(scene.groups.size(), 0);
  bool camera_moves = false;
  for (uint32_t i = 0; i < k; ++i) {
    // The ends exactly: the shutter's own numbers.
    const double open = settings.shutter_open, close = settings.shutter_close;
    const double offset = i + 1 == k ? close : open + (close - open) * double(i) / double(k - 1);
    motion->times.push_back(offset);
    Scene pose = load_pose(offset);
    check_topology(scene, pose, offset);

    if (!default_camera && (camera_moves || !same_pose(pose.camera, scene.camera))) {
      if (!camera_moves) motion->cameras.assign(i, scene.camera);
      camera_moves = true;
      motion->cameras.push_back(pose.camera);
    }
    for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
      if (still_mesh[m]) continue;
      if (mesh_at[m] < 0) {
        if (same_pose(pose.meshes[m], scene.meshes[m])) continue;
        if (emits(scene, scene.meshes[m])) {
          still_mesh[m] = 1;
          motion->still.push_back("mesh " + scene.meshes[m].origin +
                                  " emits light: it is drawn where the frame puts it");
          continue;
        }
        mesh_at[m] = static_cast<int32_t>(motion->meshes.size());
        SceneMotion::MeshPoses p{m, {}, {}};
        p.positions.assign(i, scene.meshes[m].positions);
        if (!scene.meshes[m].normals.empty()) p.normals.assign(i, scene.meshes[m].normals);
        motion->meshes.push_back(std::move(p));
      }
      SceneMotion::MeshPoses& p = motion->meshes[size_t(mesh_at[m])];
      p.positions.push_back(std::move(pose.meshes[m].positions));
      if (!scene.meshes[m].normals.empty()) p.normals.push_back(std::move(pose.meshes[m].normals));
    }
    for (uint32_t s = 0; s < scene.spheres.size(); ++s) {
      if (still_sphere[s]) continue;
      if (sphere_at[s] < 0) {
        if (same_pose(pose.spheres[s], scene.spheres[s])) continue;
        if (scene.materials[scene.spheres[s].material].is_emissive()) {
          still_sphere[s] = 1;
          motion->still.push_back("sphere " + std::to_string(s) +
                                  " emits light: it is drawn where the frame puts it");
          continue;
        }
        sphere_at[s] = static_cast<int32_t>(motion->spheres.size());
        motion->spheres.push_back({s, std::vector<Sphere>(i, scene.spheres[s])});
      }
      motion->spheres[size_t(sphere_at[s])].poses.push_back(pose.spheres[s]);
    }
    for (uint32_t g = 0; g < scene.groups.size(); ++g) {
      if (group_changes[g]) continue;
      for (uint32_t m = 0; m < scene.groups[g].meshes.size(); ++m) {
        if (same_pose(pose.groups[g].meshes[m], scene.groups[g].meshes[m])) continue;
        group_changes[g] = 1;
        motion->still.push_back("group \"" + scene.groups[g].name +
                                "\" changes shape: only its placements move");
        break;
      }
    }
    for (uint32_t n = 0; n < scene.instances.size(); ++n) {
      if (still_instance[n]) continue;
      const Instance& at = scene.instances[n];
      if (instance_at[n] < 0) {
        if (pose.instances[n].world_from_object == at.world_from_object) continue;
        const MeshGroup& group = scene.groups[at.group];
        if (group_emits(scene, group)) {
          still_instance[n] = 1;
          motion->still.push_back("a placement of group \"" + group.name +
                                  "\" emits light: it is drawn where the frame puts it");
          continue;
        }
        instance_at[n] = static_cast<int32_t>(motion->instances.size());
        motion->instances.push_back(
            {n, std::vector<std::array<double, 16>>(i, at.world_from_object)});
      }
      motion->instances[size_t(instance_at[n])].poses.push_back(
          pose.instances[n].world_from_object);
    }
  }
  return motion;
}

void check_shutter_ends(const Scene& scene, const RenderSettings& settings,
                        const PoseLoader& load_pose) {
  if (!settings.shutter_is_open() || !scene.animation) return;
  for (const double offset : {double(settings.shutter_open), double(settings.shutter_close)})
    check_topology(scene, load_pose(offset), offset);
}

void add_motion(Scene& scene, const RenderSettings& settings, const GltfOptions& gltf,
                const std::filesystem::path& root) {
  scene.motion = find_motion(scene, settings, [&](double offset) {
    return load_scene_pose(scene.source, gltf, root, scene.frame, offset);
  });
  if (!scene.motion) return;
  for (const std::string& s : scene.motion->still)
    scene.warnings.push_back(scene.source.string() + ": motion blur: " + s);
}

}  // namespace rayfarm
