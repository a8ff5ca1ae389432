#include "common/scene/instances.h"

#include <algorithm>
#include <utility>

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

bool group_emits(const Scene& scene, const MeshGroup& group) {
  for (const TriangleMesh& m : group.meshes) {
    for (const uint32_t material : m.materials) {
      if (material < scene.materials.size() && scene.materials[material].is_emissive()) return true;
    }
  }
  return false;
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
  if (t.determinant() < 0.0) {
    // A mirror image reverses every triangle's winding; swapping two corners restores it.
    for (size_t i = 0; i + 2 < out.indices.size(); i += 3)
      std::swap(out.indices[i + 1], out.indices[i + 2]);
  }
  return out;
}

size_t flatten_instances(Scene& scene, bool emissive_only) {
  std::vector<bool> emits;
  for (const MeshGroup& g : scene.groups) emits.push_back(!emissive_only || group_emits(scene, g));
  std::vector<Instance> kept;
  size_t flattened = 0;
  for (const Instance& instance : scene.instances) {
    if (!emits.at(instance.group)) {
      kept.push_back(instance);
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
