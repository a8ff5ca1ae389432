#include "common/scene/instances.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/limits.h"
#include "common/math/wide.h"

namespace rayfarm {

Transform instance_transform(const Instance& instance) {
  const auto& m = instance.world_from_object;
  return Transform({m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11]});
}

uint64_t group_triangle_count(const MeshGroup& group) {
  uint64_t n = 0;
  for (const TriangleMesh& m : group.meshes) n += m.triangle_count();
  return n;
}

bool meshes_emit(const Scene& scene, const std::vector<TriangleMesh>& meshes) {
  for (const TriangleMesh& m : meshes) {
    for (const uint32_t material : m.materials) {
      if (material < scene.materials.size() && scene.materials[material].is_emissive()) return true;
    }
  }
  return false;
}

bool group_emits(const Scene& scene, const MeshGroup& group) {
  return meshes_emit(scene, group.meshes);
}

bool has_light(const Scene& scene) {
  if (!scene.point_lights.empty() || !scene.spot_lights.empty() ||
      !scene.directional_lights.empty() || !is_black(scene.background) ||
      (scene.environment && !is_black(scene.environment->scale)) ||
      meshes_emit(scene, scene.meshes))
    return true;
  for (const Sphere& s : scene.spheres)
    if (s.material < scene.materials.size() && scene.materials[s.material].is_emissive())
      return true;
  // A group lights the scene when some instance places it: each group looked at once.
  std::vector<uint8_t> placed(scene.groups.size(), 0);
  for (const Instance& instance : scene.instances)
    if (instance.group < placed.size()) placed[instance.group] = 1;
  for (size_t g = 0; g < placed.size(); ++g)
    if (placed[g] && group_emits(scene, scene.groups[g])) return true;
  return false;
}

namespace {

void extend(WideVec3& lo, WideVec3& hi, const WideVec3& p) {
  lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
  hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
}

}  // namespace

void group_box(const MeshGroup& group, WideVec3& lo, WideVec3& hi) {
  lo = {1e300, 1e300, 1e300};
  hi = {-1e300, -1e300, -1e300};
  for (const TriangleMesh& m : group.meshes) {
    for (const Vec3& p : m.positions) extend(lo, hi, wide(p));
  }
}

namespace {

WideVec3 box_corner(const WideVec3& lo, const WideVec3& hi, int corner) {
  return {corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z};
}

}  // namespace

bool placed_in_range(const MeshGroup& group, const Transform& t) {
  WideVec3 lo, hi;
  group_box(group, lo, hi);
  return box_placed_in_range(lo, hi, t);
}

bool box_placed_in_range(const WideVec3& lo, const WideVec3& hi, const Transform& t) {
  if (lo.x > hi.x) return true;  // no points
  for (int corner = 0; corner < 8; ++corner) {
    const WideVec3 p = t.point(box_corner(lo, hi, corner));
    if (!(std::fabs(p.x) <= kMaxCoordinate && std::fabs(p.y) <= kMaxCoordinate &&
          std::fabs(p.z) <= kMaxCoordinate)) {
      return false;
    }
  }
  return true;
}

void extend_bounds(const Scene& scene, WideVec3& lo, WideVec3& hi) {
  for (const TriangleMesh& m : scene.meshes) {
    for (const Vec3& p : m.positions) extend(lo, hi, wide(p));
  }
  for (const Sphere& s : scene.spheres) {
    const WideVec3 c = wide(s.center);
    const double r = s.radius;
    extend(lo, hi, {c.x - r, c.y - r, c.z - r});
    extend(lo, hi, {c.x + r, c.y + r, c.z + r});
  }
  std::vector<std::pair<WideVec3, WideVec3>> boxes(scene.groups.size());
  for (size_t g = 0; g < scene.groups.size(); ++g)
    group_box(scene.groups[g], boxes[g].first, boxes[g].second);
  for (const Instance& instance : scene.instances) {
    const auto& [glo, ghi] = boxes.at(instance.group);
    if (glo.x > ghi.x) continue;
    const Transform t = instance_transform(instance);
    for (int corner = 0; corner < 8; ++corner)
      extend(lo, hi, t.point(box_corner(glo, ghi, corner)));
  }
}

TriangleMesh place_mesh(const TriangleMesh& mesh, const Transform& t) {
  TriangleMesh out = mesh;
  for (Vec3& p : out.positions) {
    const WideVec3 w = t.point(wide(p));
    p = Vec3(static_cast<float>(w.x), static_cast<float>(w.y), static_cast<float>(w.z));
  }
  // The cofactor matrix is det * M^-T: it turns normals inwards when the transform mirrors.
  const double outward = t.determinant() < 0.0 ? -1.0 : 1.0;
  for (Vec3& n : out.normals) {
    if (is_black(n)) continue;  // "no normal here" stays so
    const WideVec3 m = t.normal(wide(n));
    const double len = outward * length(m);
    n = Vec3(static_cast<float>(m.x / len), static_cast<float>(m.y / len),
             static_cast<float>(m.z / len));
  }
  for (Vec4& tangent : out.tangents) {
    const WideVec3 m = t.vector(WideVec3{tangent.x, tangent.y, tangent.z});
    const double len = length(m);
    if (!(len > 0.0) || !std::isfinite(len)) continue;  // unusable either way: left as it was
    // A mirror keeps the tangent but turns the bitangent: the handedness flips with it.
    tangent = Vec4(static_cast<float>(m.x / len), static_cast<float>(m.y / len),
                   static_cast<float>(m.z / len), static_cast<float>(outward) * tangent.w);
  }
  if (t.determinant() < 0.0) {
    // A mirror image reverses every triangle's winding; swapping two corners restores it.
    for (size_t i = 0; i + 2 < out.indices.size(); i += 3)
      std::swap(out.indices[i + 1], out.indices[i + 2]);
  }
  return out;
}

const InstanceBudget::Facts& InstanceBudget::facts(const Scene& scene, uint32_t group) {
  if (groups_.size() <= group) groups_.resize(size_t(group) + 1);
  Facts& f = groups_[group];
  if (!f.known) {
    const MeshGroup& g = scene.groups[group];
    f.known = true;
    f.triangles = group_triangle_count(g);
    f.emits = group_emits(scene, g);
    group_box(g, f.lo, f.hi);
  }
  return f;
}

std::optional<std::string> InstanceBudget::add(const Scene& scene, uint32_t group) {
  const Facts& f = facts(scene, group);
  triangles_ += f.triangles;
  if (triangles_ > kMaxInstancedTriangles)
    return "the instances place more than " + std::to_string(kMaxInstancedTriangles) +
           " triangles in all";
  if (f.emits) {
    emissive_triangles_ += f.triangles;
    if (emissive_triangles_ > kMaxEmissiveInstancedTriangles)
      return "the instances of emissive groups place more than " +
             std::to_string(kMaxEmissiveInstancedTriangles) +
             " triangles in all (each is kept as a world triangle for light sampling)";
  }
  return std::nullopt;
}

bool InstanceBudget::placed_in_range(const Scene& scene, uint32_t group, const Transform& t) {
  const Facts& f = facts(scene, group);
  return box_placed_in_range(f.lo, f.hi, t);
}

size_t flatten_instances(Scene& scene, bool emissive_only, std::vector<uint32_t>* kept_from) {
  std::vector<bool> emits;
  for (const MeshGroup& g : scene.groups) emits.push_back(!emissive_only || group_emits(scene, g));
  std::vector<Instance> kept;
  size_t flattened = 0;
  if (kept_from != nullptr) kept_from->clear();
  for (uint32_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& instance = scene.instances[i];
    if (!emits.at(instance.group)) {
      kept.push_back(instance);
      if (kept_from != nullptr) kept_from->push_back(i);
      continue;
    }
    const Transform t = instance_transform(instance);
    for (const TriangleMesh& m : scene.groups[instance.group].meshes)
      scene.meshes.push_back(place_mesh(m, t));
    ++flattened;
  }
  scene.instances = std::move(kept);
  return flattened;
}

}  // namespace rayfarm
