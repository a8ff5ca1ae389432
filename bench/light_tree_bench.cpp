// Light selection by power against the light tree (renderer/lights/light_selection.h) at equal
// time: renders SCENE with each strategy at the same spp, alternating, ROUNDS times, and prints
// per strategy the median time, the median relMSE against a reference (the tree's, at many
// samples, its own noise subtracted) and their product, relMSE x time, whose inverse is the
// efficiency. With --build N it times instead the building of a tree over N random lights
// (random orientations, then all facing alike). The figures are in docs/benchmarks.md ("Light
// selection by a light tree").
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "common/image/error_estimate.h"
#include "common/image/fixed.h"
#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "common/util/log.h"
#include "renderer/lights/light_tree.h"
#include "renderer/renderer.h"
#include "renderer/samplers/rng.h"

namespace {

using namespace rayfarm;

struct Rendered {
  TileResult result;
  double seconds = 0.0;
  std::string plan;
};

Rendered render(const Scene& scene, LightChoice choice, uint32_t spp, uint64_t seed) {
  RenderSettings settings = scene.render;
  settings.seed = seed;
  const auto t0 = std::chrono::steady_clock::now();
  const Renderer renderer(scene, settings, BsdfKinds::kAll, choice);
  Rendered out{renderer.render({0, 0, scene.film.width, scene.film.height}, {0, spp}), 0.0,
               renderer.plan()};
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

/// Seconds to build a tree over `count` lights (small boxes in a 100-unit cube), facing random
/// ways or all down; the median of 3 builds.
double build_seconds(size_t count, bool alike) {
  Pcg32 rng(7, 1);
  std::vector<LightBounds> bounds(count);
  std::vector<int32_t> index(count);
  for (size_t i = 0; i < count; ++i) {
    const Vec3 c(100.f * rng.next_float(), 100.f * rng.next_float(), 100.f * rng.next_float());
    bounds[i].lo = c;
    bounds[i].hi = c + Vec3(0.1f);
    const float z = 1.f - 2.f * rng.next_float(), phi = 2.f * kPi * rng.next_float();
    const float r = std::sqrt(std::max(0.f, 1.f - z * z));
    bounds[i].axis = alike ? Vec3(0.f, -1.f, 0.f) : Vec3(r * std::cos(phi), r * std::sin(phi), z);
    bounds[i].intensity = 1.0 + rng.next_float();
    index[i] = static_cast<int32_t>(i);
  }
  std::vector<double> times;
  for (int k = 0; k < 3; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    const LightTree tree(bounds, index);
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    if (tree.node_count() != 2 * count - 1) std::cerr << "unexpected tree size\n";
  }
  return median(times);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"light_tree_bench: light selection by power and by the light tree at equal spp"};
  std::string path;
  uint32_t spp = 16, reference_spp = 1024, threads = 2, rounds = 3, width = 0;
  size_t build = 0;
  app.add_option("scene", path, "Scene file");
  app.add_option("--build", build, "Time building a tree over this many random lights instead");
  app.add_option("--spp", spp, "Samples per pixel of each measured render")->capture_default_str();
  app.add_option("--reference-spp", reference_spp, "Samples of the reference (light tree)")
      ->capture_default_str();
  app.add_option("--threads", threads, "Threads")->capture_default_str();
  app.add_option("--rounds", rounds, "Renders per strategy, alternating")->capture_default_str();
  app.add_option("--width", width,
                 "Film width (the height follows the aspect ratio); 0: the scene's");
  CLI11_PARSE(app, argc, argv);
  configure_logging("error");
  if (build > 0) {
    std::cout << fmt::format("{} lights: {:.3f} s facing random ways, {:.3f} s all facing alike\n",
                             build, build_seconds(build, false), build_seconds(build, true));
    return 0;
  }
  if (path.empty()) {
    std::cerr << "light_tree_bench: a scene file, or --build N\n";
    return 2;
  }
  Scene scene = load_scene(path);
  add_motion(scene, scene.render);  // a scene's own shutter blurs what moves
  if (width > 0) {
    scene.film.height = std::max<uint32_t>(1, scene.film.height * width / scene.film.width);
    scene.film.width = width;
  }

  tbb::task_arena arena(static_cast<int>(threads));
  arena.execute([&] {
    const Rendered ref = render(scene, LightChoice::kTree, reference_spp, 999);
    const size_t values = ref.result.sum.size();
    std::vector<double> ref_mean(values), ref_var(values);
    double noise = 0.0;
    for (size_t i = 0; i < values; ++i) {
      const double n = reference_spp;
      ref_mean[i] = from_fixed(ref.result.sum[i]) / n;
      ref_var[i] = std::max(0.0, from_fixed(ref.result.sum_sq[i]) / n - ref_mean[i] * ref_mean[i]) /
                   (n - 1.0);
      noise += ref_var[i] / (ref_mean[i] * ref_mean[i] + kRelMseEpsilon) / double(values);
    }
    std::cout << fmt::format(
        "{}: {}x{}, reference {} spp in {:.1f} s (relMSE of its noise {:.3g}, "
        "subtracted)\n{}\n",
        path, scene.film.width, scene.film.height, reference_spp, ref.seconds, noise, ref.plan);
    const char* names[2] = {"power", "light tree"};
    const LightChoice choices[2] = {LightChoice::kPower, LightChoice::kTree};
    std::vector<double> seconds[2], errors[2], products[2];
    for (uint32_t round = 0; round < rounds; ++round) {
      for (int c = 0; c < 2; ++c) {
        const Rendered r = render(scene, choices[c], spp, 17 + round);
        double rel = 0.0;
        for (size_t i = 0; i < values; ++i) {
          const double d = from_fixed(r.result.sum[i]) / spp - ref_mean[i];
          rel += d * d / (ref_mean[i] * ref_mean[i] + kRelMseEpsilon) / double(values);
        }
        rel = std::max(rel - noise, 0.05 * rel);
        seconds[c].push_back(r.seconds);
        errors[c].push_back(rel);
        products[c].push_back(rel * r.seconds);
        std::cout << fmt::format("round {} {:>10}: {:.3f} s, relMSE {:.4g}\n", round + 1, names[c],
                                 r.seconds, rel);
      }
    }
    std::cout << fmt::format(
        "\n| selection | spp | median time (s) | median relMSE | relMSE x time |\n"
        "| --- | --- | --- | --- | --- |\n");
    for (int c = 0; c < 2; ++c) {
      std::cout << fmt::format("| {} | {} | {:.3f} | {:.4g} | {:.4g} |\n", names[c], spp,
                               median(seconds[c]), median(errors[c]), median(products[c]));
    }
    std::cout << fmt::format("efficiency light tree / power: {:.2f}\n",
                             median(products[0]) / median(products[1]));
  });
  return 0;
}
