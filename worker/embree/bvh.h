#pragma once
// The only module that calls Embree. The renderer sees intersect(ray) and occluded(segment).
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/math/vec3.h"

namespace rayfarm {

/// A ray: origin, direction (need not be unit length) and the parametric interval (tnear, tfar).
struct Ray {
  Vec3 org;
  Vec3 dir;
  float tnear = 0.f;
  float tfar = 3.0e38f;
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
  /// Decides whether a candidate hit counts (cut-outs): keep(context, geom, prim, u, v, p) with
  /// geom as in RayHit, (u, v) a triangle's barycentrics and p the point on the ray.
  struct HitFilter {
    bool (*keep)(const void* context, uint32_t geom, uint32_t prim, float u, float v,
                 const Vec3& p) = nullptr;
    const void* context = nullptr;
  };
  /// Triangle input: positions and 3 indices per triangle, and the filter of its hits (null:
  /// every hit counts, and none is filtered at no cost).
  struct Mesh {
    const std::vector<Vec3>* positions;
    const std::vector<uint32_t>* indices;
    const HitFilter* filter = nullptr;
  };
  /// Sphere input: centre and radius.
  struct SphereInput {
    Vec3 center;
    float radius;
  };

  /// One placement of a group: its index in `groups`, and world from object as 3x4 rows.
  struct InstanceInput {
    uint32_t group;
    std::array<float, 12> world_from_object;
  };

  /// Builds the BVH. Mesh i gets geometry id i. Each group becomes one Embree scene, built
  /// once and shared by every instance that places it. Throws std::runtime_error with Embree's
  /// message.
  /// A group mesh's filter is called for hits through every instance of the group, with geom
  /// the mesh's index within the group.
  Bvh(const std::vector<Mesh>& meshes, const std::vector<SphereInput>& spheres,
      const HitFilter* sphere_filter = nullptr, const std::vector<std::vector<Mesh>>& groups = {},
      const std::vector<InstanceInput>& instances = {});
  ~Bvh();
  Bvh(const Bvh&) = delete;
  Bvh& operator=(const Bvh&) = delete;

  /// Closest hit in (tnear, tfar), if any.
  std::optional<RayHit> intersect(const Ray& ray) const;
  /// True when anything lies in (tnear, tfar) along the ray.
  bool occluded(const Ray& ray) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rayfarm
