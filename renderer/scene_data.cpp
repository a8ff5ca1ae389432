#include "renderer/scene_data.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "common/math/wide.h"
#include "common/scene/instances.h"
#include "common/scene/motion.h"
#include "renderer/bsdfs/microfacet.h"
#include "renderer/motion_blend.h"

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
  std::vector<uint32_t> kept;
  flattened_ = flatten_instances(scene_, true, &kept);
  build_textures();
  build_coat_tables();
  build_motion(kept);
  std::vector<Bvh::Mesh> meshes;
  for (size_t m = 0; m < scene_.meshes.size(); ++m) {
    const TriangleMesh& mesh = scene_.meshes[m];
    mesh_offset_.push_back(triangles_.size());
    add_triangles(mesh, triangles_);
    meshes.push_back({&mesh.positions, &mesh.indices});
    if (moves_ && mesh_motion_[m] >= 0)
      meshes.back().poses = &scene_.motion->meshes[size_t(mesh_motion_[m])].positions;
    interpolates_.push_back(!mesh.normals.empty() || (uses_uv_ && !mesh.uvs.empty()));
  }
  std::vector<Bvh::SphereInput> spheres;
  for (const Sphere& s : scene_.spheres) spheres.push_back({s.center, s.radius});
  sphere_lights_.assign(scene_.spheres.size(), -1);
  std::vector<std::vector<Bvh::Mesh>> groups;
  for (const MeshGroup& g : scene_.groups) {
    groups.emplace_back();
    for (const TriangleMesh& mesh : g.meshes)
      groups.back().push_back({&mesh.positions, &mesh.indices});
  }
  const Bvh::HitFilter* sphere_filter = nullptr;
  build_surface(meshes, sphere_filter, groups);
  build_instances();
  std::vector<Bvh::InstanceInput> placements;
  for (size_t i = 0; i < instances_.size(); ++i) {
    placements.push_back({instances_[i].group, instances_[i].m, {}});
    if (moves_) placements.back().poses = instance_poses_[i];
  }
  const auto none = [](const std::vector<uint8_t>& v) {
    return std::none_of(v.begin(), v.end(), [](uint8_t x) { return x != 0; });
  };
  const bool vertex_colours = std::any_of(scene_.materials.begin(), scene_.materials.end(),
                                          [](const Material& m) { return m.vertex_colours; });
  plain_ = !uses_uv_ && !uses_surface_ && !vertex_colours && none(interpolates_) &&
           none(group_interpolates_);
  // A moving mesh interpolates its own posed attributes (resolve_moving()).
  for (size_t m = 0; m < mesh_motion_.size(); ++m)
    if (mesh_motion_[m] >= 0) interpolates_[m] = 0;
  bvh_ = std::make_unique<Bvh>(meshes, spheres, sphere_filter, groups, placements, sphere_poses_);
}

void SceneData::build_motion(const std::vector<uint32_t>& kept) {
  mesh_motion_.assign(scene_.meshes.size(), -1);
  sphere_motion_.assign(scene_.spheres.size(), -1);
  instance_poses_.assign(scene_.instances.size(), {});
  const SceneMotion* motion = scene_.motion.get();
  if (motion == nullptr || !motion->moves()) return;
  moves_ = true;
  poses_ = static_cast<uint32_t>(motion->steps());
  for (size_t k = 0; k < motion->meshes.size(); ++k)
    mesh_motion_.at(motion->meshes[k].mesh) = static_cast<int32_t>(k);
  for (size_t k = 0; k < motion->spheres.size(); ++k)
    sphere_motion_.at(motion->spheres[k].sphere) = static_cast<int32_t>(k);
  if (!motion->spheres.empty()) {
    for (uint32_t pose = 0; pose < poses_; ++pose) {
      sphere_poses_.emplace_back();
      for (uint32_t i = 0; i < scene_.spheres.size(); ++i) {
        const Sphere& s = sphere_motion_[i] >= 0
                              ? motion->spheres[size_t(sphere_motion_[i])].poses[pose]
                              : scene_.spheres[i];
        sphere_poses_.back().push_back({s.center, s.radius});
      }
    }
  }
  // Instances left after flattening (emissive groups' placements are world meshes now).
  std::vector<int64_t> left(scene_.instances.size() + flattened_, -1);  // scene index -> left
  for (size_t i = 0; i < kept.size(); ++i) left.at(kept[i]) = static_cast<int64_t>(i);
  for (const SceneMotion::InstancePoses& p : motion->instances) {
    if (p.instance >= left.size() || left[p.instance] < 0) continue;  // flattened: still
    const auto i = static_cast<size_t>(left[p.instance]);
    // World from object as 3x4 float rows, as the frame's placement is stored (instance_info).
    for (const std::array<double, 16>& m : p.poses) {
      std::array<float, 12> rows;
      for (size_t e = 0; e < 12; ++e) rows[e] = static_cast<float>(m[e]);
      instance_poses_[i].push_back(rows);
    }
  }
}

SceneData::InstanceInfo SceneData::instance_info(const std::array<double, 12>& rows,
                                                 uint32_t group) {
  const Transform t(rows);
  InstanceInfo info{};
  info.group = group;
  info.norm = 0.f;
  for (int r = 0; r < 3; ++r) {
    double row = 0.0;
    for (int c = 0; c < 4; ++c) {
      info.m[4 * r + c] = static_cast<float>(t.at(r, c));
      if (c < 3) row += std::fabs(t.at(r, c));
    }
    info.norm = std::max(info.norm, static_cast<float>(row));
  }
  // Columns of the normals' matrix: the images of the unit normals.
  const double outward = t.determinant() < 0.0 ? -1.0 : 1.0;
  info.handedness = static_cast<float>(outward);
  for (int c = 0; c < 3; ++c) {
    const WideVec3 col = t.normal({c == 0 ? 1.0 : 0.0, c == 1 ? 1.0 : 0.0, c == 2 ? 1.0 : 0.0});
    info.normal[c] = static_cast<float>(outward * col.x);
    info.normal[3 + c] = static_cast<float>(outward * col.y);
    info.normal[6 + c] = static_cast<float>(outward * col.z);
  }
  return info;
}

const SceneData::InstanceInfo& SceneData::instance_at(uint32_t index, float time,
                                                      InstanceInfo& scratch) const {
  const std::vector<std::array<float, 12>>& poses = instance_poses_[index];
  if (poses.empty()) return instances_[index];
  // The placement Embree traced: the poses' matrices blended element by element.
  const PoseBlend b = pose_blend(poses_, time);
  std::array<double, 12> rows;
  for (size_t e = 0; e < 12; ++e) rows[e] = blend(poses[b.i][e], poses[b.i + 1][e], b.f);
  scratch = instance_info(rows, instances_[index].group);
  return scratch;
}

const Sphere& SceneData::sphere_at(uint32_t index, float time, Sphere& scratch) const {
  if (!moves_ || sphere_motion_[index] < 0) return scene_.spheres[index];
  const std::vector<Sphere>& poses = scene_.motion->spheres[size_t(sphere_motion_[index])].poses;
  const PoseBlend b = pose_blend(poses_, time);
  const Sphere &a = poses[b.i], &c = poses[b.i + 1];
  scratch = scene_.spheres[index];
  scratch.center = blend(a.center, c.center, b.f);
  scratch.radius = blend(a.radius, c.radius, b.f);
  // The texture frame turns with the sphere: blended, then made orthonormal again.
  const Vec3 z = unit_or_zero(blend(a.axis_z, c.axis_z, b.f));
  const Vec3 x0 = blend(a.axis_x, c.axis_x, b.f);
  const Vec3 x = unit_or_zero(x0 - z * dot(x0, z));
  if (!is_black(z) && !is_black(x)) {
    scratch.axis_z = z;
    scratch.axis_x = x;
    scratch.axis_y = cross(z, x);
  } else {
    scratch.axis_x = a.axis_x;
    scratch.axis_y = a.axis_y;
    scratch.axis_z = a.axis_z;
  }
  return scratch;
}

SurfaceHit SceneData::resolve_moving(const Ray& ray, const RayHit& hit) const {
  const SceneMotion::MeshPoses& poses = scene_.motion->meshes[size_t(mesh_motion_[hit.geom])];
  const TriangleMesh& mesh = scene_.meshes[hit.geom];
  const uint32_t* idx = &mesh.indices[3 * size_t(hit.prim)];
  const PoseBlend b = pose_blend(poses_, ray.time);
  const std::vector<Vec3>&p0 = poses.positions[b.i], &p1 = poses.positions[b.i + 1];
  const Vec3 v0 = blend(p0[idx[0]], p1[idx[0]], b.f), v1 = blend(p0[idx[1]], p1[idx[1]], b.f),
             v2 = blend(p0[idx[2]], p1[idx[2]], b.f);
  const TriangleInfo& tri = triangles_[mesh_offset_[hit.geom] + hit.prim];
  SurfaceHit s;
  s.p = v0 + (v1 - v0) * hit.u + (v2 - v0) * hit.v;
  s.n = Vec3(0.f, 0.f, 1.f);
  (void)triangle_normal(v0, v1, v2, s.n);
  s.ns = s.n;
  s.uv = {hit.u, hit.v};
  // The blend's own rounding follows the poses' magnitudes, which may exceed the blended
  // triangle's where coordinates cancel: the larger bound of the three.
  s.p_error = std::max({triangle_point_error(v0, v1, v2),
                        triangle_point_error(p0[idx[0]], p0[idx[1]], p0[idx[2]]),
                        triangle_point_error(p1[idx[0]], p1[idx[1]], p1[idx[2]])});
  s.material = tri.material;
  s.light = tri.light;  // -1: emitters do not move (common/scene/motion.h)
  s.time = ray.time;
  if (!poses.normals.empty()) {
    const std::vector<Vec3>&n0 = poses.normals[b.i], &n1 = poses.normals[b.i + 1];
    const std::array<Vec3, 3> normals{blend(n0[idx[0]], n1[idx[0]], b.f),
                                      blend(n0[idx[1]], n1[idx[1]], b.f),
                                      blend(n0[idx[2]], n1[idx[2]], b.f)};
    interpolate(mesh, hit, s, &normals);
  } else if (uses_uv_ && !mesh.uvs.empty()) {
    interpolate(mesh, hit, s);
  }
  return s;
}

void SceneData::add_triangles(const TriangleMesh& mesh, std::vector<TriangleInfo>& out) {
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3& a = mesh.positions[mesh.indices[3 * t]];
    const Vec3& b = mesh.positions[mesh.indices[3 * t + 1]];
    const Vec3& c = mesh.positions[mesh.indices[3 * t + 2]];
    TriangleInfo info{
        a, b - a, c - a, Vec3(0.f, 0.f, 1.f), triangle_point_error(a, b, c), mesh.materials[t], -1};
    // In double: in float the cross product of edges longer than ~1e19 overflows, and such
    // triangles were taken for degenerate ones and shaded with the fixed normal.
    if (!triangle_normal(a, b, c, info.n)) {
      ++degenerate_;  // never hit in practice; a fixed normal keeps the shading finite
    }
    out.push_back(info);
  }
}

void SceneData::build_instances() {
  for (const MeshGroup& g : scene_.groups) {
    group_first_mesh_.push_back(static_cast<uint32_t>(group_mesh_offset_.size()));
    for (const TriangleMesh& mesh : g.meshes) {
      group_mesh_offset_.push_back(group_triangles_.size());
      add_triangles(mesh, group_triangles_);
      group_interpolates_.push_back(!mesh.normals.empty() || (uses_uv_ && !mesh.uvs.empty()));
    }
  }
  for (const Instance& instance : scene_.instances) {
    const Transform t = instance_transform(instance);
    std::array<double, 12> rows;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) rows[size_t(4 * r + c)] = t.at(r, c);
    instances_.push_back(instance_info(rows, instance.group));
  }
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

void SceneData::build_coat_tables() {
  for (Material& m : scene_.materials) {
    auto* p = std::get_if<PlasticMaterial>(&m.kind);
    if (p == nullptr) continue;
    const bool textured = p->alpha.is_textured();
    // Below kSmoothAlpha the coating is smooth, and its model needs no table.
    if (!textured && !(p->alpha.value >= kSmoothAlpha)) continue;
    const float alpha = textured ? 0.f : p->alpha.value;
    for (const auto& t : coat_tables_) {
      if (t->ior() == p->ior && t->type() == p->distribution && t->textured() == textured &&
          t->alpha() == alpha)
        p->coat_table = t.get();
    }
    if (p->coat_table == nullptr) {
      coat_tables_.push_back(
          std::make_unique<RoughCoatTable>(p->ior, p->distribution, alpha, textured));
      p->coat_table = coat_tables_.back().get();
    }
  }
}

void SceneData::set_light_index(uint32_t geom, uint32_t prim, int32_t light) {
  if (geom == kSphereGeometry) {
    sphere_lights_[prim] = light;
  } else {
    triangles_[mesh_offset_[geom] + prim].light = light;
  }
}

SurfaceHit SceneData::resolve_sphere(const Ray& ray, const RayHit& hit) const {
  if (moves_ && sphere_motion_[hit.prim] >= 0) {
    Sphere posed;
    return resolve_sphere(ray, hit, sphere_at(hit.prim, ray.time, posed));
  }
  return resolve_sphere(ray, hit, scene_.spheres[hit.prim]);
}

SurfaceHit SceneData::resolve_sphere(const Ray& ray, const RayHit& hit,
                                     const Sphere& sphere) const {
  SurfaceHit s;
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
  s.time = ray.time;
  return s;
}

Vec2 SceneData::sphere_uv(const Sphere& sphere, const Vec3& n) const {
  // Angles in the sphere's own frame; the poles and the seam get u = 0.
  const float x = dot(n, sphere.axis_x), y = dot(n, sphere.axis_y), z = dot(n, sphere.axis_z);
  float phi = std::atan2(y, x);
  if (phi < 0.f) phi += 2.f * kPi;
  return {phi * (0.5f * kInvPi), std::acos(std::clamp(z, -1.f, 1.f)) * kInvPi};
}

SurfaceHit SceneData::resolve_instanced(const Ray& ray, const RayHit& hit) const {
  InstanceInfo posed;
  const InstanceInfo& in = moves_ ? instance_at(hit.inst, ray.time, posed) : instances_[hit.inst];
  const size_t mesh = group_first_mesh_[in.group] + hit.geom;
  const TriangleInfo& tri = group_triangles_[group_mesh_offset_[mesh] + hit.prim];
  const Vec3 po = tri.v0 + tri.e1 * hit.u + tri.e2 * hit.v;
  const auto& m = in.m;
  auto unit_normal = [&in](const Vec3& n) {
    const auto& a = in.normal;
    const Vec3 w(a[0] * n.x + a[1] * n.y + a[2] * n.z, a[3] * n.x + a[4] * n.y + a[5] * n.z,
                 a[6] * n.x + a[7] * n.y + a[8] * n.z);
    const float len = length(w);
    return len > 0.f ? w / len : Vec3(0.f, 0.f, 1.f);
  };
  SurfaceHit s;
  s.p = Vec3(m[0] * po.x + m[1] * po.y + m[2] * po.z + m[3],
             m[4] * po.x + m[5] * po.y + m[6] * po.z + m[7],
             m[8] * po.x + m[9] * po.y + m[10] * po.z + m[11]);
  s.n = unit_normal(tri.n);
  s.ns = s.n;
  s.uv = {hit.u, hit.v};
  // The object-space error grown by the transform, plus the rounding of the transform itself
  // (three products and three sums per component, with the same margin as the triangles').
  const Vec3 mag(
      std::fabs(m[0] * po.x) + std::fabs(m[1] * po.y) + std::fabs(m[2] * po.z) + std::fabs(m[3]),
      std::fabs(m[4] * po.x) + std::fabs(m[5] * po.y) + std::fabs(m[6] * po.z) + std::fabs(m[7]),
      std::fabs(m[8] * po.x) + std::fabs(m[9] * po.y) + std::fabs(m[10] * po.z) + std::fabs(m[11]));
  s.p_error = in.norm * tri.p_error + 4.f * max_component(mag) * gamma_bound(7);
  s.material = tri.material;
  s.light = -1;  // emissive groups are placed as world meshes
  s.time = ray.time;
  if (group_interpolates_[mesh]) {
    // Interpolated in object space against the object's normal, then placed; a point that keeps
    // its flat normal keeps ns == n bit for bit.
    SurfaceHit local;
    local.n = tri.n;
    local.ns = tri.n;
    local.uv = s.uv;
    interpolate(scene_.groups[in.group].meshes[hit.geom], hit, local);
    s.uv = local.uv;
    if (!(local.ns == tri.n)) s.ns = unit_normal(local.ns);
  }
  return s;
}

void SceneData::interpolate(const TriangleMesh& mesh, const RayHit& hit, SurfaceHit& s,
                            const std::array<Vec3, 3>* normals) const {
  const uint32_t* idx = &mesh.indices[3 * size_t(hit.prim)];
  const float b0 = 1.f - hit.u - hit.v;
  if (!mesh.normals.empty()) {
    const Vec3& n0 = normals ? (*normals)[0] : mesh.normals[idx[0]];
    const Vec3& n1 = normals ? (*normals)[1] : mesh.normals[idx[1]];
    const Vec3& n2 = normals ? (*normals)[2] : mesh.normals[idx[2]];
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
