#pragma once
// Scenes built in code for renderer tests, so that they do not depend on the parser.
#include "common/scene/scene.h"

namespace rayfarm::testing {

/// A camera inside a closed sphere of albedo `rho` whose inner surface emits `le`.
/// Every pixel's exact radiance is le / (1 - rho).
inline Scene furnace_scene(float rho, float le, uint32_t size = 8) {
  Scene s;
  s.film = {size, size};
  s.camera.eye = {0.f, 0.f, 0.f};
  s.camera.look_at = {0.f, 0.f, 1.f};
  s.camera.fov_y_deg = 90.f;
  Material m;
  m.name = "shell";
  m.kind = DiffuseMaterial{Vec3(rho)};
  m.emission = Vec3(le);
  m.two_sided = true;
  s.materials.push_back(m);
  s.spheres.push_back({Vec3(0.3f, -0.2f, 0.1f), 2.f, 0});
  s.render.max_depth = 1000;
  return s;
}

/// A small room (diffuse walls) with an emissive ceiling quad, a point light, and a mirror and
/// a glass sphere: every material and light kind in a few primitives.
inline Scene small_room_scene(uint32_t width = 24, uint32_t height = 16) {
  Scene s;
  s.film = {width, height};
  s.camera.eye = {0.f, 0.f, -3.f};
  s.camera.look_at = {0.f, 0.f, 0.f};
  s.camera.fov_y_deg = 50.f;
  auto add_material = [&](MaterialKind kind, Vec3 emission = Vec3(0.f)) {
    Material m;
    m.kind = kind;
    m.emission = emission;
    s.materials.push_back(m);
    return static_cast<uint32_t>(s.materials.size() - 1);
  };
  const uint32_t white = add_material(DiffuseMaterial{Vec3(0.7f)});
  const uint32_t red = add_material(DiffuseMaterial{Vec3(0.7f, 0.1f, 0.1f)});
  const uint32_t phong =
      add_material(PhongMaterial{Vec3(0.2f, 0.5f, 0.7f) * 0.6f, Vec3(0.3f), 20.f});
  const uint32_t light = add_material(DiffuseMaterial{Vec3(0.f)}, Vec3(8.f));
  const uint32_t mirror = add_material(MirrorMaterial{Vec3(0.9f)});
  const uint32_t glass = add_material(DielectricMaterial{});
  TriangleMesh mesh;
  auto quad = [&](Vec3 c, Vec3 e1, Vec3 e2, uint32_t mat) {
    const auto base = static_cast<uint32_t>(mesh.positions.size());
    mesh.positions.insert(mesh.positions.end(), {c, c + e1, c + e1 + e2, c + e2});
    mesh.indices.insert(mesh.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    mesh.materials.insert(mesh.materials.end(), {mat, mat});
  };
  quad({-1, -1, -1}, {2, 0, 0}, {0, 0, 2}, white);             // floor, facing +y... either side scatters
  quad({-1, 1, -1}, {0, 0, 2}, {2, 0, 0}, white);              // ceiling
  quad({-1, -1, 1}, {2, 0, 0}, {0, 2, 0}, phong);              // back wall
  quad({-1, -1, -1}, {0, 2, 0}, {0, 0, 2}, red);               // left wall
  quad({1, -1, -1}, {0, 0, 2}, {0, 2, 0}, white);              // right wall
  quad({-0.3f, 0.99f, -0.3f}, {0.6f, 0, 0}, {0, 0, 0.6f}, light);  // light, front face -y
  s.meshes.push_back(mesh);
  s.spheres.push_back({{-0.45f, -0.6f, 0.3f}, 0.4f, mirror});
  s.spheres.push_back({{0.45f, -0.6f, -0.1f}, 0.4f, glass});
  s.point_lights.push_back({{0.5f, 0.5f, -0.5f}, Vec3(0.5f)});
  s.render.max_depth = 12;
  return s;
}

}  // namespace rayfarm::testing
