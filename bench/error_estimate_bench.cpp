// What the master computes after each pass of a job, on a synthetic film of SIZE x SIZE pixels:
// the whole image's estimated error, the per-tile figures (the worst tile), the variance layer
// and the mean image. All of it runs on the master's reactor thread, so its time is time in which
// heartbeats and results wait; it must stay well below the liveness window on large images.
//
// Usage: error_estimate_bench [--size S] [--tile T] [--spp N] [--runs R]
#include <algorithm>
#include <chrono>
#include <functional>
#include <iostream>
#include <random>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "common/image/error_estimate.h"
#include "common/image/film.h"

namespace {

using Clock = std::chrono::steady_clock;

double seconds_of(const std::function<void()>& work, int runs) {
  std::vector<double> times;
  for (int r = 0; r < runs; ++r) {
    const auto start = Clock::now();
    work();
    times.push_back(std::chrono::duration<double>(Clock::now() - start).count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"error_estimate_bench: the master's per-pass error figures on a synthetic film"};
  uint32_t size = 2048, tile = 64, spp = 16;
  int runs = 3;
  app.add_option("--size", size, "film width and height")->capture_default_str();
  app.add_option("--tile", tile, "tile size")->capture_default_str();
  app.add_option("--spp", spp, "samples per pixel in the film")->capture_default_str();
  app.add_option("--runs", runs, "runs of each measurement (median printed)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  // One unit covering the film: noisy pixels around a smooth gradient, a few fireflies.
  rayfarm::TileResult r({0, 0, size, size}, {0, spp});
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (size_t i = 0; i < r.sum.size(); ++i) {
    const double base = 0.1 + 0.8 * double(i % (size * 3)) / (size * 3);
    double s = 0, s2 = 0;
    for (uint32_t k = 0; k < spp; ++k) {
      const double v = base * (u(rng) < 0.001 ? 1000.0 : 2.0 * u(rng));
      s += v;
      s2 += v * v;
    }
    r.sum[i] = rayfarm::to_fixed(s);
    r.sum_sq[i] = rayfarm::to_fixed(s2);
  }
  rayfarm::Film film(size, size);
  film.add(r);
  const auto tiles = rayfarm::split_tiles({size, size}, tile);

  double whole = 0, worst = 0;
  const double t_whole = seconds_of([&] { whole = rayfarm::estimate_error(film).rel_mse; }, runs);
  const double t_tiles = seconds_of(
      [&] {
        worst = 0;
        for (const auto& rect : tiles)
          worst = std::max(worst, rayfarm::estimate_error(film, rect).rel_mse);
      },
      runs);
  const double t_variance = seconds_of([&] { (void)rayfarm::variance_rgb(film); }, runs);
  const double t_mean = seconds_of([&] { (void)film.mean_rgb(); }, runs);
  const double pixels = double(size) * size;
  std::cout << fmt::format(
      "film {0}x{0}, {1} spp, tiles {2}: whole-image estimate {3:.3f} s ({4:.0f} ns/pixel, relMSE "
      "{5:.4g}), per-tile estimates {6:.3f} s (worst {7:.4g}), variance layer {8:.3f} s, mean "
      "image {9:.3f} s; per pass in all {10:.3f} s\n",
      size, spp, tile, t_whole, t_whole / pixels * 1e9, whole, t_tiles, worst, t_variance, t_mean,
      t_whole + t_tiles + t_variance + t_mean);
}
