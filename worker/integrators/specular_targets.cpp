#include "worker/integrators/specular_targets.h"

#include <algorithm>
#include <cmath>

#include "common/scene/motion.h"

namespace rayfarm {

namespace {

// The bounding sphere (centre of the box, farthest point's distance) of the triangles of `mesh`
// whose material is specular, mapped by the affine `m` (row-major 4x4; null: identity). False
// when there is none.
bool specular_bounds(const TriangleMesh& mesh, const std::vector<bool>& specular,
                     const std::array<double, 16>* m, SpecularTarget& out) {
  const auto place = [m](const Vec3& p) {
    if (!m) return std::array<double, 3>{p.x, p.y, p.z};
    const auto& a = *m;
    return std::array<double, 3>{a[0] * p.x + a[1] * p.y + a[2] * p.z + a[3],
                                 a[4] * p.x + a[5] * p.y + a[6] * p.z + a[7],
                                 a[8] * p.x + a[9] * p.y + a[10] * p.z + a[11]};
  };
  std::array<double, 3> lo{HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  bool any = false;
  const size_t n = mesh.triangle_count();
  const auto each_vertex = [&](auto&& f) {
    for (size_t t = 0; t < n; ++t) {
      const uint32_t mat = mesh.materials[t];
      if (mat >= specular.size() || !specular[mat]) continue;
      for (int v = 0; v < 3; ++v) f(place(mesh.positions[mesh.indices[3 * t + v]]));
    }
  };
  each_vertex([&](const std::array<double, 3>& p) {
    any = true;
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
  });
  if (!any) return false;
  const std::array<double, 3> c{0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]),
                                0.5 * (lo[2] + hi[2])};
  double r2 = 0.0;
  each_vertex([&](const std::array<double, 3>& p) {
    const double dx = p[0] - c[0], dy = p[1] - c[1], dz = p[2] - c[2];
    r2 = std::max(r2, dx * dx + dy * dy + dz * dz);
  });
  out.center = Vec3(static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2]));
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
    for (const TriangleMesh& mesh : scene.groups[inst.group].meshes)
      if (specular_bounds(mesh, specular, &inst.world_from_object, t)) targets.push_back(t);
  }
  return SpecularTargets(std::move(targets));
}

}  // namespace rayfarm
