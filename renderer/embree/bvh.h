#pragma once
// The only module that calls Embree. The renderer sees intersect(ray) and occluded(segment).
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/math/vec3.h"

namespace rayfarm {

/// A ray: origin, direction (need not be unit length), the parametric interval (tnear, tfar),
/// and the time within the shutter in [0, 1] at which it looks at moving geometry.
struct Ray {
  Vec3 org;
  Vec3 dir;
  float tnear = 0.f;
  float tfar = 3.0e38f;
  float time = 0.f;
};

/// A closest hit: which primitive, where along the ray, and its barycentrics (triangles).
struct RayHit {
  float t = 0.f;
  uint32_t geom = 0;  ///< mesh index (within the instance's group), or kSphereGeometry
  uint32_t prim = 0;  ///< triangle index within the mesh, or sphere index
  float u = 0.f, v = 0.f;
  uint32_t inst = 0xffffffffu;  ///< instance index, or kNoInstance for world geometry
};

/// RayHit::inst of a hit on world (not instanced) geometry.
inline constexpr uint32_t kNoInstance = 0xffffffffu;

/// Geometry id of the sphere set in RayHit::geom.
inline constexpr uint32_t kSphereGeometry = 0xfffffffeu;

/// Triangle meshes and spheres in one Embree BVH.
class Bvh {
 public:
  /// Decides whether a candidate hit counts (cut-outs): keep(context, geom, prim, u, v, p, time)
  /// with geom as in RayHit, (u, v) a triangle's barycentrics, p the point on the ray and time
  /// the ray's.
  struct HitFilter {
    bool (*keep)(const void* context, uint32_t geom, uint32_t prim, float u, float v, const Vec3& p,
                 float time) = nullptr;
    const void* context = nullptr;
  };
  /// Triangle input: positions and 3 indices per triangle, and the filter of its hits (null:
  /// every hit counts, and none is filtered at no cost). A moving mesh gives its positions at
  /// each of the shutter's poses instead (at least two, evenly spaced in time from 0 to 1; its
  /// vertices move linearly between them); `positions` is then not read.
  struct Mesh {
    const std::vector<Vec3>* positions;
    const std::vector<uint32_t>* indices;
    const HitFilter* filter = nullptr;
    const std::vector<std::vector<Vec3>>* poses = nullptr;
  };
  /// Sphere input: centre and radius.
  struct SphereInput {
    Vec3 center;
    float radius;
  };

  /// One placement of a group: its index in `groups`, and world from object as 3x4 rows; a
  /// moving one at each pose instead (interpolated linearly, element by element).
  struct InstanceInput {
    uint32_t group;
    std::array<float, 12> world_from_object;
    std::vector<std::array<float, 12>> poses;
  };

  /// Builds the BVH. Mesh i gets geometry id i. Each group becomes one Embree scene, built
  /// once and shared by every instance that places it. Throws std::runtime_error with Embree's
  /// message.
  /// A group mesh's filter is called for hits through every instance of the group, with geom
  /// the mesh's index within the group.
  /// `sphere_poses`, when not empty, gives every sphere at each pose (some sphere moves).
  Bvh(const std::vector<Mesh>& meshes, const std::vector<SphereInput>& spheres,
      const HitFilter* sphere_filter = nullptr, const std::vector<std::vector<Mesh>>& groups = {},
      const std::vector<InstanceInput>& instances = {},
      const std::vector<std::vector<SphereInput>>& sphere_poses = {});
  ~Bvh();
  Bvh(const Bvh&) = delete;
  Bvh& operator=(const Bvh&) = delete;

  /// Closest hit in (tnear, tfar), if any.
  std::optional<RayHit> intersect(const Ray& ray) const;
  /// intersect() for the path loop: true and the hit in `hit` when there is one (`hit` is
  /// otherwise left as it was); no optional to pass back through memory.
  bool intersect(const Ray& ray, RayHit& hit) const;
  /// True when anything lies in (tnear, tfar) along the ray.
  bool occluded(const Ray& ray) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rayfarm
