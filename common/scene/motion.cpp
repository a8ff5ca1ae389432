#include "common/scene/motion.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

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
        a.indices != b.indices)
      refuse("mesh " + b.origin + " changes its vertices or triangles");
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
  std::vector<Scene> poses;
  poses.reserve(k);
  for (uint32_t i = 0; i < k; ++i) {
    // The ends exactly: the shutter's own numbers.
    const double open = settings.shutter_open, close = settings.shutter_close;
    const double offset = i + 1 == k ? close : open + (close - open) * double(i) / double(k - 1);
    motion->times.push_back(offset);
    poses.push_back(load_pose(offset));
    check_topology(scene, poses.back(), offset);
  }
  const auto moving = [&](const auto& pick) {
    for (const Scene& pose : poses)
      if (!same_pose(pick(pose), pick(scene))) return true;
    return false;
  };

  if (moving([](const Scene& s) -> const Camera& { return s.camera; })) {
    for (const Scene& pose : poses) motion->cameras.push_back(pose.camera);
  }
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    if (!moving([m](const Scene& s) -> const TriangleMesh& { return s.meshes[m]; })) continue;
    if (emits(scene, scene.meshes[m])) {
      motion->still.push_back("mesh " + scene.meshes[m].origin +
                              " emits light: it is drawn where the frame puts it");
      continue;
    }
    SceneMotion::MeshPoses p{m, {}, {}};
    for (Scene& pose : poses) {
      p.positions.push_back(std::move(pose.meshes[m].positions));
      if (!scene.meshes[m].normals.empty()) p.normals.push_back(std::move(pose.meshes[m].normals));
    }
    motion->meshes.push_back(std::move(p));
  }
  for (uint32_t s = 0; s < scene.spheres.size(); ++s) {
    if (!moving([s](const Scene& x) -> const Sphere& { return x.spheres[s]; })) continue;
    if (scene.materials[scene.spheres[s].material].is_emissive()) {
      motion->still.push_back("sphere " + std::to_string(s) +
                              " emits light: it is drawn where the frame puts it");
      continue;
    }
    SceneMotion::SpherePoses p{s, {}};
    for (const Scene& pose : poses) p.poses.push_back(pose.spheres[s]);
    motion->spheres.push_back(std::move(p));
  }
  for (uint32_t g = 0; g < scene.groups.size(); ++g) {
    for (uint32_t i = 0; i < scene.groups[g].meshes.size(); ++i) {
      if (moving([g, i](const Scene& s) -> const TriangleMesh& { return s.groups[g].meshes[i]; })) {
        motion->still.push_back("group \"" + scene.groups[g].name +
                                "\" changes shape: only its placements move");
        break;
      }
    }
  }
  for (uint32_t i = 0; i < scene.instances.size(); ++i) {
    bool moves = false;
    for (const Scene& pose : poses)
      moves = moves || pose.instances[i].world_from_object != scene.instances[i].world_from_object;
    if (!moves) continue;
    const MeshGroup& group = scene.groups[scene.instances[i].group];
    if (group_emits(scene, group)) {
      motion->still.push_back("a placement of group \"" + group.name +
                              "\" emits light: it is drawn where the frame puts it");
      continue;
    }
    SceneMotion::InstancePoses p{i, {}};
    for (const Scene& pose : poses) p.poses.push_back(pose.instances[i].world_from_object);
    motion->instances.push_back(std::move(p));
  }
  return motion;
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
