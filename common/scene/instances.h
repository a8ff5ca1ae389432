#pragma once
// Instances of mesh groups (Scene::groups, Scene::instances): their transforms, and placing a
// group's meshes in the world where a consumer needs world-space triangles.
#include <cstdint>

#include "common/math/transform.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// The instance's world_from_object as a Transform (its last row is 0 0 0 1).
Transform instance_transform(const Instance& instance);

/// Triangles the group holds.
uint64_t group_triangle_count(const MeshGroup& group);

/// True when some triangle of `meshes` has an emissive material of `scene`.
bool meshes_emit(const Scene& scene, const std::vector<TriangleMesh>& meshes);
/// True when some triangle of the group has an emissive material of `scene`.
bool group_emits(const Scene& scene, const MeshGroup& group);
/// Whether anything in the scene can light it: a light, an environment or background that is not
/// black, or an emissive material on a world mesh, a sphere or a placed group. Without one, every
/// image is black (kNoLightWarning).
bool has_light(const Scene& scene);

/// What a scene's instances place in all, against kMaxInstancedTriangles and (instances of
/// emissive groups, which workers copy into the world for light sampling: they cost memory per
/// instance) kMaxEmissiveInstancedTriangles. What it needs of a group is found once, so that a
/// group placed a million times is not read a million times.
class InstanceBudget {
 public:
  /// Counts one more instance of group `group` of `scene`; why it is refused, or nothing.
  std::optional<std::string> add(const Scene& scene, uint32_t group);
  /// placed_in_range() for group `group` of `scene`.
  bool placed_in_range(const Scene& scene, uint32_t group, const Transform& t);

 private:
  struct Facts {
    bool known = false, emits = false;
    uint64_t triangles = 0;
    WideVec3 lo, hi;
  };
  const Facts& facts(const Scene& scene, uint32_t group);

  std::vector<Facts> groups_;
  uint64_t triangles_ = 0, emissive_triangles_ = 0;
};

/// Whether every point of the group, placed by `t`, stays within kMaxCoordinate: the placed
/// corners of its bounding box do.
bool placed_in_range(const MeshGroup& group, const Transform& t);

/// The group's bounding box in its own space; lo > hi when it has no points.
void group_box(const MeshGroup& group, WideVec3& lo, WideVec3& hi);

/// placed_in_range() for a group whose box group_box() gave: for a group placed many times,
/// whose points are then read once.
bool box_placed_in_range(const WideVec3& lo, const WideVec3& hi, const Transform& t);

/// Extends the box [lo, hi] by the points of the scene's world meshes, its spheres (their boxes)
/// and its instances (each by its group's bounding box, placed: a box that holds the placed
/// points).
void extend_bounds(const Scene& scene, WideVec3& lo, WideVec3& hi);

/// A world-space copy of `mesh` placed by `t`: positions moved, normals by the inverse
/// transpose, tangents by the matrix (handedness flipped under a mirror), and the winding reversed
/// under a mirror so that front faces stay front faces.
TriangleMesh place_mesh(const TriangleMesh& mesh, const Transform& t);

/// Replaces instances by world-space copies of their group's meshes appended to scene.meshes:
/// every instance, or (`emissive_only`) those whose group has emissive triangles, since area
/// lights need their triangles in world space. Returns the number of instances flattened;
/// `kept`, when given, receives the index each instance left had before.
size_t flatten_instances(Scene& scene, bool emissive_only, std::vector<uint32_t>* kept = nullptr);

}  // namespace rayfarm
