// Error against time for each integrator on a room lit by one light of the same power: a square
// ceiling light at the normal size (side 0.5), tiny (1e-6 of its area, 1e6 times its radiance),
// large (side 1.8, most of the ceiling), or a sphere (radius 0.2) hanging below the ceiling,
// where the light's 1/r^2 and cosine factors vary most across it.
// The error is the RMS difference from a reference rendered with MIS at many samples, with the
// reference's own variance subtracted (its per-pixel sums carry it). Prints one line per
// (light, integrator, spp); the figures are in docs/stability.md.
#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "common/util/log.h"
#include "renderer/renderer.h"

namespace {

using namespace rayfarm;

uint32_t add(Scene& s, Vec3 albedo, Vec3 emission = Vec3(0.f)) {
  Material m;
  m.kind = DiffuseMaterial{albedo};
  m.emission = emission;
  s.materials.push_back(m);
  return static_cast<uint32_t>(s.materials.size() - 1);
}

void quad(Scene& s, Vec3 c, Vec3 e1, Vec3 e2, uint32_t material) {
  TriangleMesh mesh;
  mesh.positions = {c, c + e1, c + e1 + e2, c + e2};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  mesh.materials = {material, material};
  s.meshes.push_back(mesh);
}

/// The closed room of tests/renderer/stability_scenes.h (room_with_light), light side `side`; a
/// sphere of radius `sphere` at (0, 0.7, 0) instead of the square when sphere > 0.
Scene room(float side, float le, uint32_t size, float sphere = 0.f) {
  Scene s;
  s.film = {size, size};
  s.camera.eye = {0.f, 0.2f, -0.95f};
  s.camera.look_at = {0.f, -0.3f, 1.f};
  s.camera.fov_y_deg = 70.f;
  const uint32_t wall = add(s, Vec3(0.5f));
  const uint32_t red = add(s, Vec3(0.6f, 0.1f, 0.1f));
  const uint32_t lamp = add(s, Vec3(0.f), Vec3(le));
  quad(s, {-1, -1, -1}, {0, 0, 2}, {2, 0, 0}, wall);
  quad(s, {-1, 1, -1}, {2, 0, 0}, {0, 0, 2}, wall);
  quad(s, {-1, -1, 1}, {2, 0, 0}, {0, 2, 0}, wall);
  quad(s, {-1, -1, -1}, {0, 2, 0}, {2, 0, 0}, wall);
  quad(s, {-1, -1, -1}, {0, 0, 2}, {0, 2, 0}, red);
  quad(s, {1, -1, -1}, {0, 2, 0}, {0, 0, 2}, wall);
  if (sphere > 0.f) {
    s.spheres.push_back({{0.f, 0.7f, 0.f}, sphere, lamp});
  } else {
    quad(s, {-0.5f * side, 0.999f, -0.5f * side}, {side, 0, 0}, {0, 0, side}, lamp);
  }
  s.render.max_depth = 8;
  return s;
}

struct Rendered {
  TileResult result;
  double seconds = 0.0;
};

Rendered render(const Scene& scene, IntegratorType integrator, uint32_t spp, uint64_t seed) {
  RenderSettings settings = scene.render;
  settings.integrator = integrator;
  settings.spp = spp;
  settings.seed = seed;
  const Renderer renderer(scene, settings);
  const auto t0 = std::chrono::steady_clock::now();
  Rendered out{renderer.render({0, 0, scene.film.width, scene.film.height}, {0, spp}), 0.0};
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"light_size_bench: error against time per integrator, normal and tiny light"};
  uint32_t size = 32, reference_spp = 4096, threads = 2, max_spp = 1024;
  std::vector<std::string> lights = {"normal", "tiny"};
  app.add_option("--size", size, "Film side in pixels")->capture_default_str();
  app.add_option("--reference-spp", reference_spp, "MIS samples of the reference")->capture_default_str();
  app.add_option("--max-spp", max_spp, "Largest spp measured (powers of 4 from 4)")->capture_default_str();
  app.add_option("--threads", threads, "Threads")->capture_default_str();
  app.add_option("--lights", lights, "Lights: normal, tiny, large, sphere")->capture_default_str();
  std::vector<std::string> integrators = {"naive", "nee", "mis"};
  app.add_option("--integrators", integrators, "Integrators measured")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  // The max_depth truncation warnings (about 0.5% of the throughput here) would drown the table.
  configure_logging("error");

  tbb::task_arena arena(static_cast<int>(threads));
  arena.execute([&] {
    std::cout << fmt::format("{:>6} {:>6} {:>6} {:>9} {:>11} {:>9} {:>13} {:>8}\n", "light",
                             "integr", "spp", "seconds", "rmse", "rel.rmse", "rmse*sqrt(s)",
                             "dropped");
    for (const std::string& name : lights) {
      // The same power: radiance x area (one-sided square: its area; sphere: 4 pi r^2).
      const float side = name == "tiny" ? 5e-4f : name == "large" ? 1.8f : 0.5f;
      const float radius = name == "sphere" ? 0.2f : 0.f;
      const float area = radius > 0.f ? 4.f * kPi * radius * radius : side * side;
      const float le = 8.f * (0.5f * 0.5f) / area;
      const Scene scene = room(side, le, size, radius);
      const Rendered ref = render(scene, IntegratorType::kMis, reference_spp, 999);
      const size_t values = ref.result.sum.size();
      std::vector<double> ref_mean(values), ref_var(values);
      double ref_level = 0.0;
      for (size_t i = 0; i < values; ++i) {
        const double n = reference_spp;
        ref_mean[i] = from_fixed(ref.result.sum[i]) / n;
        ref_var[i] = std::max(0.0, from_fixed(ref.result.sum_sq[i]) / n - ref_mean[i] * ref_mean[i]) / (n - 1.0);
        ref_level += ref_mean[i] / double(values);
      }
      for (const std::string& integrator_text : integrators) {
        const std::optional<IntegratorType> parsed = parse_integrator(integrator_text);
        if (!parsed) {
          std::cerr << "unknown integrator " << integrator_text << "\n";
          return;
        }
        const IntegratorType integrator = *parsed;
        for (uint32_t spp = 4; spp <= max_spp; spp *= 4) {
          const Rendered r = render(scene, integrator, spp, 17 + spp);
          double mse = 0.0;
          for (size_t i = 0; i < values; ++i) {
            const double d = from_fixed(r.result.sum[i]) / spp - ref_mean[i];
            mse += (d * d - ref_var[i]) / double(values);  // the reference's own noise removed
          }
          const double rmse = std::sqrt(std::max(0.0, mse));
          std::cout << fmt::format("{:>6} {:>6} {:>6} {:>9.3f} {:>11.4g} {:>9.3g} {:>13.4g} {:>8}\n",
                                   name, integrator_name(integrator), spp, r.seconds, rmse,
                                   rmse / ref_level, rmse * std::sqrt(r.seconds),
                                   r.result.nonfinite);
        }
      }
    }
  });
  return 0;
}
