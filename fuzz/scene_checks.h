#pragma once
// What every scene that load_scene() accepts must satisfy: the renderer indexes with these
// numbers without checking them again.
#include <cmath>

#include "common/scene/motion.h"
#include "common/scene/scene.h"
#include "fuzz_support.h"

namespace rayfarm::fuzz {

inline bool finite_within(const Vec3& v, float limit) {
  return is_finite(v) && std::fabs(v.x) <= limit && std::fabs(v.y) <= limit &&
         std::fabs(v.z) <= limit;
}

inline void check_scene(const Scene& s) {
  require(s.film.width >= 1 && s.film.height >= 1 && s.film.width <= 16384 &&
              s.film.height <= 16384 && uint64_t{s.film.width} * s.film.height <= (1u << 26),
          "film size");
  require(finite_within(s.camera.eye, 1e17f) && finite_within(s.camera.look_at, 1e17f),
          "camera position");
  require(s.camera.fov_y_deg > 0.f && s.camera.fov_y_deg < 180.f, "fov");
  require(s.render.spp >= 1 &&
              (s.render.max_depth <= kMaxDepth || s.render.max_depth == kUnlimitedDepth) &&
              s.render.roulette_depth <= kMaxRouletteDepth,
          "render settings");
  require(!shutter_problem(s.render.shutter_open, s.render.shutter_close, s.render.motion_steps),
          "shutter");
  for (const Material& m : s.materials) {
    require(is_finite(m.emission.value) && min_component(m.emission.value) >= 0.f, "emission");
    if (const auto* d = std::get_if<DiffuseMaterial>(&m.kind)) {
      require(min_component(d->albedo) >= 0.f && max_component(d->albedo) <= 1.f, "albedo");
    }
    if (const auto* p = std::get_if<PhongMaterial>(&m.kind)) {
      require(max_component(p->kd + p->ks) <= 1.f + 1e-6f, "phong energy");
    }
    if (const auto* d = std::get_if<DielectricMaterial>(&m.kind)) {
      require(d->ior > 0.f && std::isfinite(d->ior), "ior");
    }
    if (const auto* c = std::get_if<RoughConductorMaterial>(&m.kind)) {
      require(c->alpha_u >= 0.f && c->alpha_u <= 1.f && c->alpha_v >= 0.f && c->alpha_v <= 1.f,
              "conductor alpha");
      require(min_component(c->eta) > 0.f && min_component(c->k) >= 0.f, "conductor index");
    }
    if (const auto* d = std::get_if<RoughDielectricMaterial>(&m.kind)) {
      require(d->ior > 0.f && d->alpha_u >= 0.f && d->alpha_u <= 1.f, "rough dielectric");
    }
    if (const auto* p = std::get_if<PlasticMaterial>(&m.kind)) {
      require(p->ior > 0.f && p->alpha >= 0.f && p->alpha <= 1.f, "plastic");
    }
    if (const auto* g = std::get_if<MetallicRoughnessMaterial>(&m.kind)) {
      require(g->metallic >= 0.f && g->metallic <= 1.f && g->roughness >= 0.f &&
                  g->roughness <= 1.f && g->transmission >= 0.f && g->transmission <= 1.f,
              "metallic_roughness");
    }
  }
  for (const TriangleMesh& mesh : s.meshes) {
    require(mesh.indices.size() % 3 == 0, "indices in threes");
    require(mesh.materials.size() == mesh.triangle_count(), "one material per triangle");
    for (uint32_t i : mesh.indices) require(i < mesh.positions.size(), "vertex index");
    for (uint32_t m : mesh.materials) require(m < s.materials.size(), "material index");
    for (const Vec3& p : mesh.positions) require(finite_within(p, 1e17f), "vertex range");
    require(mesh.normals.empty() || mesh.normals.size() == mesh.positions.size(), "normals");
    require(mesh.uvs.empty() || mesh.uvs.size() == mesh.positions.size(), "uvs");
    for (const Vec3& n : mesh.normals) {
      const float length = std::sqrt(dot(n, n));
      require(is_black(n) || (std::isfinite(length) && std::fabs(length - 1.f) < 1e-3f),
              "normal unit or zero");
    }
    for (const Vec2& uv : mesh.uvs) {
      require(std::isfinite(uv.x) && std::isfinite(uv.y), "uv finite");
    }
  }
  for (const Sphere& sp : s.spheres) {
    require(sp.material < s.materials.size(), "sphere material");
    require(sp.radius > 0.f && finite_within(sp.center, 1e17f), "sphere");
  }
  for (const PointLight& l : s.point_lights) require(finite_within(l.position, 1e17f), "light");
}

}  // namespace rayfarm::fuzz
