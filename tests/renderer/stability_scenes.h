#pragma once
// Scenes for the stability tests (docs/stability.md), built in code so that they can hold what
// the parser would refuse or drop (zero-area triangles, IOR 1e30) and be scaled at will.
#include <string>

#include "common/scene/parser.h"
#include "common/scene/scene.h"

namespace rayfarm::testing {

inline uint32_t add_material(Scene& s, Material m) {
  s.materials.push_back(std::move(m));
  return static_cast<uint32_t>(s.materials.size() - 1);
}

inline Material diffuse(Vec3 albedo, Vec3 emission = Vec3(0.f), bool two_sided = false) {
  Material m;
  m.kind = DiffuseMaterial{albedo};
  m.emission = emission;
  m.two_sided = two_sided;
  return m;
}

inline Material glass(float ior, Vec3 tint = Vec3(1.f)) {
  Material m;
  m.kind = DielectricMaterial{ior, tint};
  return m;
}

/// Adds the quad (c, c+e1, c+e1+e2, c+e2) as one mesh; its front faces along e1 x e2.
inline void add_quad(Scene& s, Vec3 c, Vec3 e1, Vec3 e2, uint32_t material) {
  TriangleMesh mesh;
  mesh.positions = {c, c + e1, c + e1 + e2, c + e2};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  mesh.materials = {material, material};
  mesh.origin = "quad";
  s.meshes.push_back(std::move(mesh));
}

/// A camera at `eye` looking at `look_at` with a square film of `size` pixels.
inline Scene empty_scene(Vec3 eye, Vec3 look_at, float fov, uint32_t size) {
  Scene s;
  s.film = {size, size};
  s.camera.eye = eye;
  s.camera.look_at = look_at;
  s.camera.up = {0.f, 1.f, 0.f};
  s.camera.fov_y_deg = fov;
  return s;
}

/// White glass furnace: concentric dielectric spheres (radii[i], relative ior[i] = inside over
/// outside) in a uniform background of radiance 1, seen from outside. Lossless and closed, so
/// every pixel's exact radiance is 1.
inline Scene glass_furnace(const std::vector<float>& radii, const std::vector<float>& iors,
                           uint32_t size = 8) {
  Scene s = empty_scene({0.f, 0.f, -3.f}, {0.f, 0.f, 0.f}, 30.f, size);
  s.background = Vec3(1.f);
  for (size_t i = 0; i < radii.size(); ++i) {
    s.spheres.push_back({Vec3(0.f), radii[i], add_material(s, glass(iors[i]))});
  }
  return s;
}

/// A closed room [-1, 1]^3 of diffuse walls (albedo 0.5) lit by a square ceiling light of side
/// `side` facing down, of radiance `le`; the camera inside looks at the far wall and floor.
inline Scene room_with_light(float side, float le, uint32_t size = 16) {
  Scene s = empty_scene({0.f, 0.2f, -0.95f}, {0.f, -0.3f, 1.f}, 70.f, size);
  const uint32_t wall = add_material(s, diffuse(Vec3(0.5f)));
  const uint32_t red = add_material(s, diffuse(Vec3(0.6f, 0.1f, 0.1f)));
  const uint32_t lamp = add_material(s, diffuse(Vec3(0.f), Vec3(le)));
  add_quad(s, {-1, -1, -1}, {0, 0, 2}, {2, 0, 0}, wall);  // floor
  add_quad(s, {-1, 1, -1}, {2, 0, 0}, {0, 0, 2}, wall);   // ceiling
  add_quad(s, {-1, -1, 1}, {2, 0, 0}, {0, 2, 0}, wall);   // back
  add_quad(s, {-1, -1, -1}, {0, 2, 0}, {2, 0, 0}, wall);  // front (behind the camera)
  add_quad(s, {-1, -1, -1}, {0, 0, 2}, {0, 2, 0}, red);   // left
  add_quad(s, {1, -1, -1}, {0, 2, 0}, {0, 0, 2}, wall);   // right
  // Light just below the ceiling; +x cross +z = -y: faces down.
  add_quad(s, {-0.5f * side, 0.999f, -0.5f * side}, {side, 0, 0}, {0, 0, side}, lamp);
  return s;
}

/// The bundled Cornell box at `size` pixels, every length multiplied by `scale` and then moved
/// by `offset`. Radiance does not depend on the scale, so the image must not either.
inline Scene transformed_cornell(float scale, Vec3 offset, uint32_t size) {
  Scene s = load_scene(std::string(RAYFARM_SOURCE_DIR) + "/scenes/cornell-box/scene.json");
  s.film = {size, size};
  const auto move = [&](Vec3 p) { return p * scale + offset; };
  s.camera.eye = move(s.camera.eye);
  s.camera.look_at = move(s.camera.look_at);
  s.camera.focus_distance *= scale;
  s.camera.aperture_radius *= scale;
  for (TriangleMesh& m : s.meshes) {
    for (Vec3& p : m.positions) p = move(p);
  }
  for (Sphere& sp : s.spheres) {
    sp.center = move(sp.center);
    sp.radius *= scale;
  }
  for (PointLight& l : s.point_lights) {
    l.position = move(l.position);
    l.intensity = l.intensity * (scale * scale);  // intensity / distance^2 stays the same
  }
  return s;
}

}  // namespace rayfarm::testing
