// Samples and rays per second of the renderer on one scene: renders the whole image `--runs`
// times and prints each run and the median. Scene loading and BVH building are not timed.
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <iostream>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "renderer/renderer.h"

int main(int argc, char** argv) {
  CLI::App app{"render_throughput: samples/s and rays/s of rayfarm's renderer"};
  std::string scene_path;
  uint32_t spp = 4, threads = 2, runs = 5, tile = 64;
  std::optional<uint32_t> max_depth;
  std::optional<std::string> integrator;
  bool diffuse_only = false;
  app.add_option("scene", scene_path, "Scene file")->required();
  app.add_option("--spp", spp, "Samples per pixel per run")->capture_default_str();
  app.add_option("--threads", threads, "Threads")->capture_default_str();
  app.add_option("--runs", runs, "Timed runs (median reported)")->capture_default_str();
  app.add_option("--tile", tile, "Tile size")->capture_default_str();
  app.add_option("--max-depth", max_depth, "Override the scene's max_depth");
  app.add_option("--integrator", integrator, "Override the scene's integrator");
  app.add_flag("--diffuse-only", diffuse_only,
               "Render with the BSDF that knows only diffuse materials (bench/diffuse_only.sh)");
  CLI11_PARSE(app, argc, argv);

  try {
    rayfarm::Scene scene = rayfarm::load_scene(scene_path);
    rayfarm::add_motion(scene, scene.render);  // a scene's own shutter blurs what moves
    rayfarm::RenderSettings settings = scene.render;
    settings.spp = spp;
    if (max_depth) settings.max_depth = *max_depth;
    if (integrator) settings.integrator = *rayfarm::parse_integrator(*integrator);
    const rayfarm::Renderer renderer(
        scene, settings,
        diffuse_only ? rayfarm::BsdfKinds::kDiffuseOnly : rayfarm::BsdfKinds::kAll);
    std::cout << fmt::format("scene {} {}x{}, {} spp per run, {} threads; {}\n", scene_path,
                             scene.film.width, scene.film.height, spp, threads, renderer.plan());
    rayfarm::LocalRenderOptions options;
    options.threads = threads;
    options.tile_size = tile;
    std::vector<double> spp_per_s, mrays_per_s;
    rayfarm::render_local(renderer, options);  // warm-up: page in, spin up the thread pool
    for (uint32_t r = 0; r < runs; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      const rayfarm::Film film = rayfarm::render_local(renderer, options);
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      spp_per_s.push_back(spp / s);
      mrays_per_s.push_back(double(film.rays()) / s * 1e-6);
      std::cout << fmt::format(
          "run {}: {:.3f} s, {:.2f} spp/s, {:.3f} Msamples/s, {:.2f} Mrays/s\n", r, s,
          spp_per_s.back(), spp_per_s.back() * scene.film.width * scene.film.height * 1e-6,
          mrays_per_s.back());
    }
    auto median = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[v.size() / 2];
    };
    std::cout << fmt::format("median: {:.2f} spp/s, {:.2f} Mrays/s\n", median(spp_per_s),
                             median(mrays_per_s));
  } catch (const std::exception& e) {
    std::cerr << "render_throughput: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
