#include "worker/scene_data.h"

#include <cmath>
#include <cstring>
#include <limits>

namespace rayfarm {
namespace {

constexpr float gamma_bound(int n) {
  constexpr float eps = std::numeric_limits<float>::epsilon() * 0.5f;
  return (n * eps) / (1.f - n * eps);
}

}  // namespace

// The factor 4 is a margin for the intersector's own rounding on top of the interpolation's.
float triangle_point_error(const Vec3& v0, const Vec3& v1, const Vec3& v2) {
  return 4.f * max_component(abs(v0) + abs(v1) + abs(v2)) * gamma_bound(7);
}

float sphere_point_error(const Vec3& center, float radius) {
  return 4.f * (max_component(abs(center)) + radius) * gamma_bound(8);
}

SceneData::SceneData(const Scene& scene) : scene_(scene) {
  std::vector<Bvh::Mesh> meshes;
  triangles_.resize(scene_.meshes.size());
  mesh_lights_.resize(scene_.meshes.size());
  for (size_t m = 0; m < scene_.meshes.size(); ++m) {
    const TriangleMesh& mesh = scene_.meshes[m];
    auto& info = triangles_[m];
    info.resize(mesh.triangle_count());
    mesh_lights_[m].assign(mesh.triangle_count(), -1);
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
      const Vec3& a = mesh.positions[mesh.indices[3 * t]];
      const Vec3& b = mesh.positions[mesh.indices[3 * t + 1]];
      const Vec3& c = mesh.positions[mesh.indices[3 * t + 2]];
      const Vec3 ng = cross(b - a, c - a);
      const float len = length(ng);
      info[t].p_error = triangle_point_error(a, b, c);
      if (!(len > 0.f) || !std::isfinite(len)) {
        ++degenerate_;
        info[t].n = Vec3(0.f, 0.f, 1.f);
        continue;
      }
      info[t].n = ng / len;
    }
    meshes.push_back({&mesh.positions, &mesh.indices});
  }
  std::vector<Bvh::SphereInput> spheres;
  for (const Sphere& s : scene_.spheres) spheres.push_back({s.center, s.radius});
  sphere_lights_.assign(scene_.spheres.size(), -1);
  bvh_ = std::make_unique<Bvh>(meshes, spheres);
}

void SceneData::set_light_index(uint32_t geom, uint32_t prim, int32_t light) {
  if (geom == kSphereGeometry) {
    sphere_lights_[prim] = light;
  } else {
    mesh_lights_[geom][prim] = light;
  }
}

SurfaceHit SceneData::resolve(const Ray& ray, const RayHit& hit) const {
  SurfaceHit s;
  if (hit.geom == kSphereGeometry) {
    const Sphere& sphere = scene_.spheres[hit.prim];
    const Vec3 raw = ray.org + ray.dir * hit.t;
    Vec3 n = raw - sphere.center;
    const float len = length(n);
    n = len > 0.f ? n / len : Vec3(0.f, 0.f, 1.f);
    s.p = sphere.center + n * sphere.radius;
    s.n = n;
    s.p_error = sphere_point_error(sphere.center, sphere.radius);
    s.material = sphere.material;
    s.light = sphere_lights_[hit.prim];
    return s;
  }
  const TriangleMesh& mesh = scene_.meshes[hit.geom];
  const uint32_t* idx = &mesh.indices[3 * size_t{hit.prim}];
  const Vec3& v0 = mesh.positions[idx[0]];
  const Vec3& v1 = mesh.positions[idx[1]];
  const Vec3& v2 = mesh.positions[idx[2]];
  const float b0 = 1.f - hit.u - hit.v;
  s.p = v0 * b0 + v1 * hit.u + v2 * hit.v;
  const TriangleInfo& info = triangles_[hit.geom][hit.prim];
  s.p_error = info.p_error;
  s.n = info.n;
  s.material = mesh.materials[hit.prim];
  s.light = mesh_lights_[hit.geom][hit.prim];
  return s;
}

}  // namespace rayfarm
