#include "renderer/integrators/specular_targets.h"

#include <algorithm>
#include <cmath>

#include "common/math/transform.h"
#include "common/math/wide.h"
#include "common/scene/instances.h"
#include "common/scene/motion.h"

namespace rayfarm {

namespace {

// The bounding sphere (centre of the box, farthest point's distance) of the triangles of `mesh`
// whose material is specular, placed by `placement` (null: where they are). False when there is
// none.
bool specular_bounds(const TriangleMesh& mesh, const std::vector<bool>& specular,
                     const Transform* placement, SpecularTarget& out) {
  const auto each_vertex = [&](auto&& f) {
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
      const uint32_t mat = mesh.materials[t];
      if (mat >= specular.size() || !specular[mat]) continue;
      for (int v = 0; v < 3; ++v) {
        const WideVec3 p = wide(mesh.positions[mesh.indices[3 * t + v]]);
        f(placement ? placement->point(p) : p);
      }
    }
  };
  WideVec3 lo{HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  bool any = false;
  each_vertex([&](const WideVec3& p) {
    any = true;
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  });
  if (!any) return false;
  const WideVec3 c{0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), 0.5 * (lo.z + hi.z)};
  double r2 = 0.0;
  each_vertex([&](const WideVec3& p) {
    const WideVec3 d = p - c;
    r2 = std::max(r2, d.x * d.x + d.y * d.y + d.z * d.z);
  });
  out.center = Vec3(static_cast<float>(c.x), static_cast<float>(c.y), static_cast<float>(c.z));
  // A little larger than exact, so that rounding in float never leaves a point of the object
  // outside its cone.
  out.radius = static_cast<float>(std::sqrt(r2) * (1.0 + 1e-5)) + 1e-6f * max_component(abs(out.center));
  return std::isfinite(out.radius) && out.radius > 0.f && is_finite(out.center);
}

}  // namespace

SpecularTargets::SpecularTargets(std::vector<SpecularTarget> targets) {
  // The largest first; ties keep the scene's order.
  std::stable_sort(targets.begin(), targets.end(),
                   [](const SpecularTarget& a, const SpecularTarget& b) {
                     return a.radius > b.radius;
                   });
  if (targets.size() > kMaxTargets) targets.resize(kMaxTargets);
  targets_ = std::move(targets);
}

SpecularTargets SpecularTargets::of_scene(const Scene& scene, const std::vector<bool>& specular) {
  // What moves within the shutter is left out: the frame's bounds do not hold it.
  std::vector<bool> moving_sphere(scene.spheres.size()), moving_mesh(scene.meshes.size()),
      moving_instance(scene.instances.size());
  if (scene.motion) {
    for (const auto& m : scene.motion->spheres)
      if (m.sphere < moving_sphere.size()) moving_sphere[m.sphere] = true;
    for (const auto& m : scene.motion->meshes)
      if (m.mesh < moving_mesh.size()) moving_mesh[m.mesh] = true;
    for (const auto& m : scene.motion->instances)
      if (m.instance < moving_instance.size()) moving_instance[m.instance] = true;
  }
  std::vector<SpecularTarget> targets;
  for (size_t i = 0; i < scene.spheres.size(); ++i) {
    const Sphere& s = scene.spheres[i];
    if (!moving_sphere[i] && s.material < specular.size() && specular[s.material] &&
        s.radius > 0.f && std::isfinite(s.radius) && is_finite(s.center))
      targets.push_back({s.center, s.radius * (1.f + 1e-5f)});
  }
  SpecularTarget t;
  for (size_t i = 0; i < scene.meshes.size(); ++i)
    if (!moving_mesh[i] && specular_bounds(scene.meshes[i], specular, nullptr, t))
      targets.push_back(t);
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (moving_instance[i] || inst.group >= scene.groups.size()) continue;
    const Transform placement = instance_transform(inst);
    for (const TriangleMesh& mesh : scene.groups[inst.group].meshes)
      if (specular_bounds(mesh, specular, &placement, t)) targets.push_back(t);
  }
  return SpecularTargets(std::move(targets));
}

}  // namespace rayfarm
