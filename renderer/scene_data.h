#pragma once
// The scene prepared for rendering: the BVH, per-triangle normals, and where each hit's
// material and light live. Built once per job; read-only while rendering.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "common/math/vec2.h"
#include "common/scene/scene.h"
#include "renderer/bsdfs/rough_coat.h"
#include "renderer/embree/bvh.h"
#include "renderer/textures/texture_set.h"

namespace rayfarm {

/// What the integrator needs to know about a hit point.
struct SurfaceHit {
  Vec3 p;  ///< position, recomputed from the primitive (not org + t dir)
  Vec3 n;  ///< unit geometric normal on the front side
  /// Unit shading normal on n's side: interpolated from a mesh's vertex normals, else n itself
  /// (bit for bit, which the integrator uses to know a flat hit).
  Vec3 ns;
  /// Texture coordinates: a mesh's interpolated ones, a sphere's angles (docs/scene-format.md),
  /// else the triangle's barycentrics. Filled only when the scene has a use for them
  /// (SceneData::uses_uv()), else the barycentrics on triangles and zero on spheres.
  Vec2 uv;
  float p_error = 0.f;  ///< offset that clears the error bound of p (scene units)
  uint32_t material = 0;
  int32_t light = -1;  ///< index into LightSet, or -1
  float time = 0.f;    ///< the ray's time within the shutter (rays leaving the hit keep it)
};

/// Derivatives and tangent directions at a hit, for normal and bump maps and anisotropic BSDFs;
/// computed only for materials that need them (SceneData::tangent_frame).
struct TangentFrame {
  Vec3 dpdu, dpdv;  ///< from the texture coordinates (or barycentrics); zero when degenerate
  Vec3 tangent;     ///< unit: the mesh's tangent, else dpdu's direction; zero when unknown
  Vec3 bitangent;   ///< unit: the direction of a normal map's +y (the image's up); may be zero
};

/// What shading a material needs beyond its BSDF, decided once per scene.
enum SurfaceNeeds : uint8_t {
  kNeedsTangentFrame = 1,  ///< an anisotropic BSDF: its frame follows the tangent
  kNeedsSurfaceMap = 2,    ///< a normal or bump map perturbs the shading normal
  kOneSided = 4,           ///< scatters nothing from behind
  kFlipBitangent = 8,      ///< the normal map's image has its origin at the top (v runs down)
  kShadingSided = 16,      ///< scatters only above the shading horizon (Material::shading_sided)
};

/// An origin for rays leaving `p` towards the side of `n`: moved `p_error` along n, then one ulp
/// further away per component, so that rounding cannot bring it back. Scale independent, since
/// p_error follows the floating-point error of p.
[[gnu::always_inline]] inline Vec3 offset_ray_origin(const Vec3& p, float p_error, const Vec3& n) {
  const Vec3 po = p + n * p_error;
  // One ulp in the direction of n per component: the bits of the magnitude up where the
  // component and n's share a sign, down where they do not, unchanged where either is zero.
  // On the bits, without branches: two of every path vertex's rays start here, and the signs
  // are unpredictable.
#if defined(__SSE2__)
  const __m128 pv = _mm_setr_ps(po.x, po.y, po.z, 0.f), nv = _mm_setr_ps(n.x, n.y, n.z, 0.f);
  const __m128i pb = _mm_castps_si128(pv);
  const __m128i step =  // -1 where the sign bits differ, else +1
      _mm_or_si128(_mm_srai_epi32(_mm_xor_si128(pb, _mm_castps_si128(nv)), 31), _mm_set1_epi32(1));
  const __m128 zero = _mm_setzero_ps();
  const __m128i move =
      _mm_castps_si128(_mm_and_ps(_mm_cmpneq_ps(pv, zero), _mm_cmpneq_ps(nv, zero)));
  alignas(16) float out[4];
  _mm_store_ps(out, _mm_castsi128_ps(_mm_add_epi32(pb, _mm_and_si128(step, move))));
  return {out[0], out[1], out[2]};
#else
  auto away = [](float v, float dir) {
    uint32_t bits, dbits;
    std::memcpy(&bits, &v, sizeof bits);
    std::memcpy(&dbits, &dir, sizeof dbits);
    const uint32_t step = 1u - (((bits ^ dbits) >> 31) << 1);  // +1, or -1 mod 2^32
    const uint32_t move = uint32_t((bits << 1) != 0) & uint32_t((dbits << 1) != 0);
    bits += step * move;
    float out;
    std::memcpy(&out, &bits, sizeof out);
    return out;
  };
  return {away(po.x, n.x), away(po.y, n.y), away(po.z, n.z)};
#endif
}

/// v made unit length; zero when it has no length (or an infinite one).
inline Vec3 unit_or_zero(const Vec3& v) {
  const float len = length(v);
  return len > 0.f && std::isfinite(len) ? v / len : Vec3(0.f);
}

/// Unit normal of triangle (a, b, c) along (b - a) x (c - a), computed in double so that edges
/// up to the format's 1e30 cannot overflow; false (and n unchanged) when it has no area.
bool triangle_normal(const Vec3& a, const Vec3& b, const Vec3& c, Vec3& n);
/// Area of triangle (a, b, c), computed in double (the float result may be infinite).
double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c);

/// Offset clearing the error of a point on a triangle (interpolated, or found by the
/// intersector, which mixes coordinates: the bound follows the largest magnitude involved).
float triangle_point_error(const Vec3& v0, const Vec3& v1, const Vec3& v2);
/// Offset clearing the error of a point projected onto a sphere.
float sphere_point_error(const Vec3& center, float radius);

class SceneData {
 public:
  explicit SceneData(const Scene& scene);

  const Scene& scene() const { return scene_; }
  const Bvh& bvh() const { return *bvh_; }
  const Material& material(uint32_t i) const { return scene_.materials[i]; }
  /// The scene's textures, indexed as Scene::textures.
  const TextureSet& textures() const { return textures_; }

  /// Resolves an Embree hit into position, normal, material and light.
  SurfaceHit resolve(const Ray& ray, const RayHit& hit) const {
    SurfaceHit s = resolve_plain(ray, hit);  // spheres and instances read their attributes
    if (hit.geom != kSphereGeometry && hit.inst == kNoInstance && interpolates_[hit.geom])
      interpolate(scene_.meshes[hit.geom], hit, s);
    return s;
  }
  /// Resolves a hit of a plain() scene: what resolve() gives there, without its test for a
  /// world mesh's vertex attributes (texture coordinates are the barycentrics, the normal flat).
  SurfaceHit resolve_plain(const Ray& ray, const RayHit& hit) const {
    if (hit.geom == kSphereGeometry) return resolve_sphere(ray, hit);
    if (hit.inst != kNoInstance) return resolve_instanced(ray, hit);
    if (moves_ && mesh_motion_[hit.geom] >= 0) return resolve_moving(ray, hit);
    const TriangleInfo& tri = triangles_[mesh_offset_[hit.geom] + hit.prim];
    SurfaceHit s;
    s.p = tri.v0 + tri.e1 * hit.u + tri.e2 * hit.v;
    s.n = tri.n;
    s.ns = tri.n;
    s.uv = {hit.u, hit.v};
    s.p_error = tri.p_error;
    s.material = tri.material;
    s.light = tri.light;
    s.time = ray.time;
    return s;
  }
  /// True when every hit is flat (no vertex normals, no normal or bump map) and no material
  /// reads a texture or needs more than its normal to shade (SurfaceNeeds): the path tracer
  /// then leaves every test for these out.
  bool plain() const { return plain_; }
  /// True when hits carry texture coordinates (some material looks them up).
  bool uses_uv() const { return uses_uv_; }
  /// True when some material has a SurfaceNeeds flag (scene_surface.cpp).
  bool uses_surface() const { return uses_surface_; }
  uint8_t surface_needs(uint32_t material) const { return surface_needs_[material]; }
  /// Derivatives and tangents at a resolved hit.
  TangentFrame tangent_frame(const RayHit& hit, const SurfaceHit& s) const;
  /// The hit mesh's vertex colour interpolated at the hit (TriangleMesh::colours); 1 where the
  /// mesh has none, and on spheres.
  Vec3 vertex_colour(const RayHit& hit) const;
  /// Whether the candidate hit (geom, prim, barycentrics u v, point p) is there: false where its
  /// material's opacity falls below its cutoff (or, partial coverage, with probability 1 - alpha).
  bool covered(uint32_t geom, uint32_t prim, float u, float v, const Vec3& p,
               float time = 0.f) const;
  /// covered() for triangle `prim` of mesh `geom` of group `group`, hit through any instance:
  /// the opacity is looked up at the object's own texture coordinates.
  bool covered_in_group(uint32_t group, uint32_t geom, uint32_t prim, float u, float v,
                        const Vec3& p) const;
  /// What the cut-out filter of one group's geometries receives: Embree reports a hit through an
  /// instance with the geometry's id within its group, so the group comes with the filter.
  struct GroupFilter {
    const SceneData* data;
    uint32_t group;
  };
  /// Light index of a primitive (-1 when it does not emit); set by LightSet.
  void set_light_index(uint32_t geom, uint32_t prim, int32_t light);
  /// Instances traced through their group's shared BVH.
  size_t instances() const { return instances_.size(); }
  /// Instances of emissive groups, placed as world meshes (appended to scene().meshes): area
  /// lights need world-space triangles.
  size_t flattened_instances() const { return flattened_; }
  /// Triangles stored for hits: the world meshes' and each group's once.
  size_t stored_triangles() const { return triangles_.size() + group_triangles_.size(); }
  /// Whether some shape moves within the shutter (common/scene/motion.h): hits then depend on
  /// the ray's time.
  bool moves() const { return moves_; }
  /// Number of triangles dropped because they have no area.
  uint64_t degenerate_triangles() const { return degenerate_; }

 private:
  Scene scene_;
  // Everything a hit on a triangle needs, in one cache-friendly record.
  struct TriangleInfo {
    Vec3 v0, e1, e2;  // p = v0 + u e1 + v e2
    Vec3 n;           // unit geometric normal, front side
    float p_error;    // triangle_point_error of its vertices
    uint32_t material;
    int32_t light;
  };
  // A placement of a group: world from object (3x4 rows, float), the normals' matrix (the
  // cofactor matrix, negated under a mirror so that front faces stay front), and the largest
  // absolute row sum of its 3x3 part (how much it can grow an error).
  struct InstanceInfo {
    std::array<float, 12> m;
    std::array<float, 9> normal;
    float norm;
    float handedness;  // -1 when the placement mirrors, else 1
    uint32_t group;
  };
  SurfaceHit resolve_sphere(const Ray& ray, const RayHit& hit) const;
  SurfaceHit resolve_sphere(const Ray& ray, const RayHit& hit, const Sphere& sphere) const;
  SurfaceHit resolve_instanced(const Ray& ray, const RayHit& hit) const;
  // A hit on a moving world mesh: its triangle posed at the ray's time.
  SurfaceHit resolve_moving(const Ray& ray, const RayHit& hit) const;
  // Sphere `index` at `time`: the scene's own when it does not move, else `scratch` filled.
  const Sphere& sphere_at(uint32_t index, float time, Sphere& scratch) const;
  // Instance `index` at `time`: the stored one when it does not move, else `scratch` filled.
  const InstanceInfo& instance_at(uint32_t index, float time, InstanceInfo& scratch) const;
  // Motion blur: which shapes move, and their poses; `kept` maps the instances left after
  // flattening to the scene's.
  void build_motion(const std::vector<uint32_t>& kept);
  void build_textures();
  // The tables of the rough plastics' coatings, one per distinct (ior, distribution, alpha),
  // their addresses written into the materials.
  void build_coat_tables();
  // Surface needs per material, and the cut-out filters of the BVH's geometries (world meshes,
  // spheres, and the meshes of groups).
  void build_surface(std::vector<Bvh::Mesh>& meshes, const Bvh::HitFilter*& sphere_filter,
                     std::vector<std::vector<Bvh::Mesh>>& groups);
  /// Whether the hit at `p` on primitive `prim` is there (cut-outs and partial coverage).
  bool opaque_at(uint32_t material, const Vec2& uv, const Vec3& p, uint32_t prim) const;
  Vec2 sphere_uv(const Sphere& sphere, const Vec3& n) const;
  void build_instances();
  void add_triangles(const TriangleMesh& mesh, std::vector<TriangleInfo>& out);
  // Shading normal and texture coordinates from a mesh's vertex attributes; `normals`, when
  // given, are the triangle's vertex normals instead of the mesh's (a moving mesh's, posed).
  void interpolate(const TriangleMesh& mesh, const RayHit& hit, SurfaceHit& s,
                   const std::array<Vec3, 3>* normals = nullptr) const;

  std::vector<TriangleInfo> triangles_;  // all meshes, mesh after mesh
  std::vector<size_t> mesh_offset_;      // index of each mesh's first triangle in triangles_
  std::vector<int32_t> sphere_lights_;
  std::vector<uint8_t> interpolates_;  // per mesh: its hits read vertex attributes
  bool uses_uv_ = false;
  bool uses_surface_ = false;
  bool plain_ = false;
  std::vector<uint8_t> surface_needs_;  // per material
  Bvh::HitFilter cut_out_filter_{};
  std::vector<GroupFilter> group_filter_contexts_;  // one per group; addresses held by Embree
  std::vector<Bvh::HitFilter> group_filters_;
  std::unique_ptr<Bvh> bvh_;
  TextureSet textures_;
  std::vector<std::unique_ptr<RoughCoatTable>> coat_tables_;
  uint64_t degenerate_ = 0;
  // Groups: their triangles in object space, stored once; group_first_mesh_ indexes
  // group_mesh_offset_ (one entry per mesh of every group, in order).
  std::vector<TriangleInfo> group_triangles_;
  std::vector<size_t> group_mesh_offset_;
  std::vector<uint32_t> group_first_mesh_;
  std::vector<uint8_t> group_interpolates_;
  std::vector<InstanceInfo> instances_;
  size_t flattened_ = 0;
  // Motion blur: poses_ poses; per world mesh and per sphere the index of its poses in
  // scene_.motion (-1: still); per instance its poses (empty: still); every sphere at each pose.
  bool moves_ = false;
  uint32_t poses_ = 0;
  std::vector<int32_t> mesh_motion_;
  std::vector<int32_t> sphere_motion_;
  std::vector<std::vector<std::array<float, 12>>> instance_poses_;
  std::vector<std::vector<Bvh::SphereInput>> sphere_poses_;
  static InstanceInfo instance_info(const std::array<double, 12>& rows, uint32_t group);
};

}  // namespace rayfarm
