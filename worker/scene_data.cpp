#include "worker/scene_data.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "common/math/wide.h"

namespace rayfarm {
namespace {

constexpr float gamma_bound(int n) {
  constexpr float eps = std::numeric_limits<float>::epsilon() * 0.5f;
  return (n * eps) / (1.f - n * eps);
}

}  // namespace

bool triangle_normal(const Vec3& a, const Vec3& b, const Vec3& c, Vec3& n) {
  const WideVec3 ng = edge_cross(a, b, c);
  const double len = length(ng);
  if (!(len > 0.0) || !std::isfinite(len)) return false;
  const Vec3 unit(static_cast<float>(ng.x / len), static_cast<float>(ng.y / len),
                  static_cast<float>(ng.z / len));
  if (!(length(unit) > 0.5f)) return false;
  n = unit;
  return true;
}

double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c) {
  return 0.5 * length(edge_cross(a, b, c));
}

// The factor 4 is a margin for the intersector's own rounding on top of the interpolation's.
float triangle_point_error(const Vec3& v0, const Vec3& v1, const Vec3& v2) {
  return 4.f * max_component(abs(v0) + abs(v1) + abs(v2)) * gamma_bound(7);
}

float sphere_point_error(const Vec3& center, float radius) {
  return 4.f * (max_component(abs(center)) + radius) * gamma_bound(8);
}

SceneData::SceneData(const Scene& scene) : scene_(scene) {
  build_textures();
  std::vector<Bvh::Mesh> meshes;
  for (const TriangleMesh& mesh : scene_.meshes) {
    mesh_offset_.push_back(triangles_.size());
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
      const Vec3& a = mesh.positions[mesh.indices[3 * t]];
      const Vec3& b = mesh.positions[mesh.indices[3 * t + 1]];
      const Vec3& c = mesh.positions[mesh.indices[3 * t + 2]];
      TriangleInfo info{a, b - a, c - a, Vec3(0.f, 0.f, 1.f), triangle_point_error(a, b, c),
                        mesh.materials[t], -1};
      // In double: in float the cross product of edges longer than ~1e19 overflows, and such
      // triangles were taken for degenerate ones and shaded with the fixed normal.
      if (!triangle_normal(a, b, c, info.n)) {
        ++degenerate_;  // never hit in practice; a fixed normal keeps the shading finite
      }
      triangles_.push_back(info);
    }
    meshes.push_back({&mesh.positions, &mesh.indices});
    interpolates_.push_back(!mesh.normals.empty() || (uses_uv_ && !mesh.uvs.empty()));
  }
  std::vector<Bvh::SphereInput> spheres;
  for (const Sphere& s : scene_.spheres) spheres.push_back({s.center, s.radius});
  sphere_lights_.assign(scene_.spheres.size(), -1);
  const Bvh::HitFilter* sphere_filter = nullptr;
  build_surface(meshes, sphere_filter);
  bvh_ = std::make_unique<Bvh>(meshes, spheres, sphere_filter);
}

void SceneData::build_textures() {
  for (const Material& m : scene_.materials) uses_uv_ = uses_uv_ || m.uses_uv();
  for (const TextureDesc& t : scene_.textures) {
    if (t.kind == TextureDesc::Kind::kCheckerboard) {
      textures_.add_checkerboard(CheckerboardTexture(Vec4(t.color0.x, t.color0.y, t.color0.z, 1.f),
                                                     Vec4(t.color1.x, t.color1.y, t.color1.z, 1.f),
                                                     t.options.transform));
      continue;
    }
    if (!t.image) {
      throw std::runtime_error("texture \"" + t.name + "\": its image " + t.file.string() +
                               " was not kept when the scene was loaded");
    }
    const uint32_t image = textures_.load_image(t.file.generic_string(), t.space, *t.image);
    textures_.add_image_texture(image, t.options);
  }
  // The decoded files now live in the texture set; the scene's copies are not needed.
  for (TextureDesc& t : scene_.textures) t.image.reset();
}

void SceneData::set_light_index(uint32_t geom, uint32_t prim, int32_t light) {
  if (geom == kSphereGeometry) {
    sphere_lights_[prim] = light;
  } else {
    triangles_[mesh_offset_[geom] + prim].light = light;
  }
}

SurfaceHit SceneData::resolve_sphere(const Ray& ray, const RayHit& hit) const {
  SurfaceHit s;
  const Sphere& sphere = scene_.spheres[hit.prim];
  const Vec3 raw = ray.org + ray.dir * hit.t;
  Vec3 n = raw - sphere.center;
  const float len = length(n);
  n = len > 0.f ? n / len : Vec3(0.f, 0.f, 1.f);
  // Reproject onto the sphere: the error then follows the sphere's size, not the ray's length.
  s.p = sphere.center + n * sphere.radius;
  s.n = n;
  s.p_error = sphere_point_error(sphere.center, sphere.radius);
  s.ns = n;
  if (uses_uv_) s.uv = sphere_uv(sphere, n);
  s.material = sphere.material;
  s.light = sphere_lights_[hit.prim];
  return s;
}

Vec2 SceneData::sphere_uv(const Sphere& sphere, const Vec3& n) const {
  // Angles in the sphere's own frame; the poles and the seam get u = 0.
  const float x = dot(n, sphere.axis_x), y = dot(n, sphere.axis_y), z = dot(n, sphere.axis_z);
  float phi = std::atan2(y, x);
  if (phi < 0.f) phi += 2.f * kPi;
  return {phi * (0.5f * kInvPi), std::acos(std::clamp(z, -1.f, 1.f)) * kInvPi};
}

void SceneData::interpolate(const RayHit& hit, SurfaceHit& s) const {
  const TriangleMesh& mesh = scene_.meshes[hit.geom];
  const uint32_t* idx = &mesh.indices[3 * size_t(hit.prim)];
  const float b0 = 1.f - hit.u - hit.v;
  if (!mesh.normals.empty()) {
    const Vec3 &n0 = mesh.normals[idx[0]], &n1 = mesh.normals[idx[1]], &n2 = mesh.normals[idx[2]];
    if (!is_black(n0) && !is_black(n1) && !is_black(n2)) {
      const Vec3 sum = n0 * b0 + n1 * hit.u + n2 * hit.v;
      const float len = length(sum);
      // Opposite normals can cancel; such a point keeps the flat normal.
      if (len > 1e-6f) s.ns = dot(sum, s.n) < 0.f ? -(sum / len) : sum / len;
    }
  }
  if (uses_uv_ && !mesh.uvs.empty()) {
    const Vec2 &t0 = mesh.uvs[idx[0]], &t1 = mesh.uvs[idx[1]], &t2 = mesh.uvs[idx[2]];
    s.uv = t0 * b0 + t1 * hit.u + t2 * hit.v;
  }
}

}  // namespace rayfarm
