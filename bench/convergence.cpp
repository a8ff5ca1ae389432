// Convergence of the three integrators: relative MSE against a high-spp reference, as a function
// of render time, for one scene (the bundled Cornell box by default; see bench/convergence.sh).
//
// Each integrator renders the whole image in passes whose cumulative spp grows by about sqrt(2)
// (1, 2, 3, 4, 6, 8, 11, 16, ...) until its time budget is spent. After every pass the image is
// compared with the reference (compare_images' relMSE: mean over values of (a-b)^2 / (b^2 + 1e-2))
// outside the timed region. The reference is our own renderer at high spp (MIS, another seed),
// made once and cached; its own noise adds about mean(var_ref / (b^2 + 1e-2)) to every measured
// relMSE, which is estimated from the reference's per-pixel sums and subtracted (both figures are
// written to the CSV).
//
// Output: one CSV per integrator (pass, spp, time_s, rel_mse, rel_mse_measured, rmse), the plot
// (relMSE against time on log-log axes, one curve per integrator, 1/t slope), and on stdout the
// table of times to reach relMSE 1e-2 and 1e-3 (interpolated on the log-log curve) and the
// equal-time comparison naive against NEE.
#include <tbb/task_arena.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "common/image/exr.h"
#include "common/image/film.h"
#include "common/image/metrics.h"
#include "common/report/plot.h"
#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "renderer/renderer.h"

namespace fs = std::filesystem;
using namespace rayfarm;

namespace {

// Seconds of CPU time used by this process (all threads). On a shared machine it measures the
// work done, whatever the other processes take; on an idle one it is threads x wall time.
double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

enum class Clock { kCpu, kWall };

struct Point {
  uint32_t pass = 0, spp = 0;
  double time_s = 0.0, wall_s = 0.0, rel_mse = 0.0, rel_mse_measured = 0.0, rmse = 0.0;
};

// Cumulative spp after each pass: 1, 2, 3, 4, 6, 8, 11, 16, 23, 32, ... (x sqrt 2, rounded).
std::vector<uint32_t> pass_schedule(uint32_t max_spp) {
  std::vector<uint32_t> out;
  for (int k = 0;; ++k) {
    const auto spp = static_cast<uint32_t>(std::lround(std::pow(2.0, k / 2.0)));
    if (spp > max_spp) break;
    if (out.empty() || spp > out.back()) out.push_back(spp);
  }
  return out;
}

// Per-pixel variance of the film's mean, RGB interleaved: (sum_sq - sum^2/n) / (n (n - 1)).
std::vector<float> variance_of_mean(const Film& film) {
  std::vector<float> var(film.sum().size());
  for (size_t p = 0; p < film.spp().size(); ++p) {
    const double n = film.spp()[p];
    for (int c = 0; c < 3; ++c) {
      const double s = from_fixed(film.sum()[p * 3 + c]), s2 = from_fixed(film.sum_sq()[p * 3 + c]);
      var[p * 3 + c] =
          n > 1 ? static_cast<float>(std::max(0.0, s2 - s * s / n) / (n * (n - 1.0))) : 0.f;
    }
  }
  return var;
}

Image film_image(const Film& film) {
  Image image;
  image.width = film.width();
  image.height = film.height();
  image.rgb = film.mean_rgb();
  return image;
}

// Renders in passes of the schedule until the time budget is spent or `on_pass(pass, film,
// seconds, wall_seconds)` (run untimed after each pass) returns false. Returns the render time.
template <class OnPass>
double render_passes(const Renderer& renderer, tbb::task_arena& arena,
                     const std::vector<uint32_t>& schedule, Clock clock, double time_budget_s,
                     OnPass&& on_pass) {
  const FilmSize size = renderer.film();
  Film film(size.width, size.height);
  double elapsed = 0.0, wall = 0.0;
  uint32_t done = 0;
  for (size_t k = 0; k < schedule.size() && elapsed < time_budget_s; ++k) {
    const double c0 = process_cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    arena.execute([&] {
      film.add(renderer.render({0, 0, size.width, size.height}, {done, schedule[k]}));
    });
    const double dw = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    wall += dw;
    elapsed += clock == Clock::kCpu ? process_cpu_seconds() - c0 : dw;
    done = schedule[k];
    if (!on_pass(static_cast<uint32_t>(k), film, elapsed, wall)) break;
  }
  return elapsed;
}

// Time at which a curve first reaches `target`, interpolated linearly in log(time)-log(error)
// between the two points that bracket it; nullopt when never reached.
std::optional<double> time_to_reach(const std::vector<Point>& curve, double target) {
  for (size_t i = 0; i < curve.size(); ++i) {
    if (curve[i].rel_mse > target) continue;
    if (i == 0) return curve[0].time_s;
    const Point& a = curve[i - 1];
    const Point& b = curve[i];
    const double f =
        (std::log(target) - std::log(a.rel_mse)) / (std::log(b.rel_mse) - std::log(a.rel_mse));
    return std::exp(std::log(a.time_s) + f * (std::log(b.time_s) - std::log(a.time_s)));
  }
  return std::nullopt;
}

// relMSE of a curve at time t, interpolated in log-log; nullopt outside the curve's time range.
std::optional<double> error_at(const std::vector<Point>& curve, double t) {
  for (size_t i = 1; i < curve.size(); ++i) {
    const Point& a = curve[i - 1];
    const Point& b = curve[i];
    if (t < a.time_s || t > b.time_s) continue;
    const double f = (std::log(t) - std::log(a.time_s)) / (std::log(b.time_s) - std::log(a.time_s));
    return std::exp(std::log(a.rel_mse) + f * (std::log(b.rel_mse) - std::log(a.rel_mse)));
  }
  return std::nullopt;
}

// Least-squares fit of log(relMSE) = log(c) - log(t) (slope fixed at -1) over the last half of
// the curve: c = relMSE x time, the constant of a converging Monte Carlo estimate.
double error_time_product(const std::vector<Point>& curve) {
  double sum = 0.0;
  size_t n = 0;
  for (size_t i = curve.size() / 2; i < curve.size(); ++i, ++n)
    sum += std::log(curve[i].rel_mse * curve[i].time_s);
  return n ? std::exp(sum / double(n)) : 0.0;
}

std::string seconds(std::optional<double> t) { return t ? fmt::format("{:.3g} s", *t) : "—"; }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "convergence: relMSE against time for naive, nee and mis against a high-spp reference"};
  std::string scene_path, out_dir = "convergence-out", plot_path, reference_path;
  uint32_t threads = 2, reference_spp = 8192, max_spp = 1u << 16, size = 0;
  double budget_s = 60.0, stop_at = 5e-4;
  std::string clock_name = "cpu";
  uint64_t seed = 1;
  std::vector<std::string> integrators{"naive", "nee", "mis"};
  app.add_option("scene", scene_path, "Scene file")->required();
  app.add_option("--threads", threads, "Render threads")->capture_default_str();
  app.add_option("--budget", budget_s, "Render seconds per integrator")->capture_default_str();
  app.add_option("--stop-at", stop_at, "Stop an integrator once its relMSE is below this")
      ->capture_default_str();
  app.add_option("--clock", clock_name,
                 "cpu: process CPU seconds (robust on a shared machine); wall")
      ->check(CLI::IsMember({"cpu", "wall"}))
      ->capture_default_str();
  app.add_option("--max-spp", max_spp, "Stop an integrator at this spp")->capture_default_str();
  app.add_option("--size", size, "Square film size instead of the scene's (0 = the scene's)")
      ->capture_default_str();
  app.add_option("--reference", reference_path,
                 "Reference EXR (with variance.R/G/B channels); made and cached when missing")
      ->required();
  app.add_option("--reference-spp", reference_spp, "spp of a reference made here (mis)")
      ->capture_default_str();
  app.add_option("--seed", seed, "Seed of the measured renders (the reference uses seed + 1000)")
      ->capture_default_str();
  app.add_option("--integrators", integrators, "Integrators to run")->capture_default_str();
  app.add_option("--out", out_dir, "Folder for the CSV files")->capture_default_str();
  app.add_option("--plot", plot_path, "Plot PNG (default OUT/convergence.png)");
  CLI11_PARSE(app, argc, argv);

  try {
    const Clock clock = clock_name == "cpu" ? Clock::kCpu : Clock::kWall;
    Scene scene = load_scene(scene_path);
    add_motion(scene, scene.render);  // a scene's own shutter blurs what moves
    if (size > 0) scene.film = {size, size};
    tbb::task_arena arena(static_cast<int>(threads));
    fs::create_directories(out_dir);
    if (plot_path.empty()) plot_path = (fs::path(out_dir) / "convergence.png").string();

    // The reference: our renderer (MIS) at high spp with an independent seed, cached.
    if (!fs::exists(reference_path)) {
      RenderSettings settings = scene.render;
      settings.integrator = IntegratorType::kMis;
      settings.spp = reference_spp;
      settings.seed = seed + 1000;
      const Renderer renderer(scene, settings);
      std::cout << fmt::format("making the reference: {} spp, mis, seed {} -> {}\n", reference_spp,
                               settings.seed, reference_path);
      Film film(scene.film.width, scene.film.height);
      const auto t0 = std::chrono::steady_clock::now();
      const uint32_t chunk = 256;
      for (uint32_t s = 0; s < reference_spp; s += chunk) {
        arena.execute([&] {
          film.add(renderer.render({0, 0, scene.film.width, scene.film.height},
                                   {s, std::min(reference_spp, s + chunk)}));
        });
      }
      Image image = film_image(film);
      const std::vector<float> var = variance_of_mean(film);
      for (int c = 0; c < 3; ++c) {
        std::vector<float>& channel = image.extra[std::string("variance.") + "RGB"[c]];
        for (size_t p = 0; p < var.size() / 3; ++p) channel.push_back(var[p * 3 + c]);
      }
      image.attributes["rayfarm:reference"] = fmt::format(
          "{} spp, mis, seed {}, max_depth {}", reference_spp, settings.seed, settings.max_depth);
      fs::create_directories(fs::path(reference_path).parent_path());
      write_exr(reference_path, image);
      std::cout << fmt::format(
          "reference made in {:.1f} s\n",
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    const Image reference = read_exr(reference_path);
    if (reference.width != scene.film.width || reference.height != scene.film.height) {
      throw std::runtime_error(fmt::format("{}: {}x{}, the film is {}x{}", reference_path,
                                           reference.width, reference.height, scene.film.width,
                                           scene.film.height));
    }
    // The reference's own noise adds E[(b - mu)^2] / (b^2 + 1e-2) to each value's relMSE. Its
    // per-pixel variance is in channels variance.R/G/B (references made here) or, RGB, in a
    // sibling STEM-variance.exr (the Blender Cycles references of tests/data/references).
    std::vector<float> ref_var(reference.rgb.size(), 0.f);
    const fs::path sibling =
        fs::path(reference_path).replace_extension().string() + "-variance.exr";
    if (reference.extra.count("variance.R")) {
      for (int c = 0; c < 3; ++c) {
        const std::vector<float>& v = reference.extra.at(std::string("variance.") + "RGB"[c]);
        for (size_t p = 0; p < v.size(); ++p) ref_var[p * 3 + c] = v[p];
      }
    } else if (fs::exists(sibling)) {
      ref_var = read_exr(sibling).rgb;
    } else {
      std::cout << "the reference has no variance: its own noise is not subtracted\n";
    }
    double ref_noise = 0.0;
    for (size_t i = 0; i < ref_var.size(); ++i) {
      const double b = reference.rgb[i];
      ref_noise += ref_var[i] / (b * b + 1e-2);
    }
    ref_noise /= double(reference.rgb.size());
    std::cout << fmt::format(
        "scene {} {}x{}, max_depth {}, {} threads, at most {:.0f} {} s per integrator "
        "(or until relMSE < {:.1e}); reference {} (its own noise: relMSE {:.2e}, "
        "subtracted)\n",
        scene_path, scene.film.width, scene.film.height, scene.render.max_depth, threads, budget_s,
        clock_name, stop_at, reference_path, ref_noise);

    const std::vector<uint32_t> schedule = pass_schedule(max_spp);
    std::map<std::string, std::vector<Point>> curves;
    std::map<std::string, double> samples_per_s;
    for (const std::string& name : integrators) {
      const std::optional<IntegratorType> type = parse_integrator(name);
      if (!type) throw std::runtime_error("unknown integrator " + name);
      RenderSettings settings = scene.render;
      settings.integrator = *type;
      settings.spp = max_spp;
      settings.seed = seed;
      const Renderer renderer(scene, settings);
      std::vector<Point>& curve = curves[name];
      const double total = render_passes(
          renderer, arena, schedule, clock, budget_s,
          [&](uint32_t k, const Film& film, double t, double wall) {
            const ImageDiff d = compare_images(film_image(film), reference);
            // Kept positive for the logarithms; the subtraction is a small correction in practice.
            const double corrected = std::max(d.rel_mse - ref_noise, 0.05 * d.rel_mse);
            curve.push_back({k, film.min_spp(), t, wall, corrected, d.rel_mse, d.rmse});
            return curve.back().rel_mse > stop_at;
          });
      samples_per_s[name] = double(curve.back().spp) * scene.film.width * scene.film.height / total;
      std::ofstream csv(fs::path(out_dir) / (name + ".csv"));
      csv << "integrator,pass,spp,time_s,wall_s,rel_mse,rel_mse_measured,rmse\n";
      for (const Point& p : curve) {
        csv << fmt::format("{},{},{},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g}\n", name, p.pass, p.spp,
                           p.time_s, p.wall_s, p.rel_mse, p.rel_mse_measured, p.rmse);
      }
      std::cout << fmt::format(
          "{:6}: {} passes, {} spp in {:.2f} {} s ({:.2f} wall s; {:.3g} Msamples per {} s), "
          "final relMSE {:.3e}\n",
          name, curve.size(), curve.back().spp, total, clock_name, curve.back().wall_s,
          samples_per_s[name] * 1e-6, clock_name, curve.back().rel_mse);
    }

    // The table: time to reach 1e-2 and 1e-3; where a curve stops short, the 1/t extrapolation
    // from its relMSE x time constant is given in brackets.
    std::cout << fmt::format(
        "\ntimes in {} seconds\n| integrator | Msamples/s | relMSE x time (s) | "
        "time to relMSE 1e-2 | time to relMSE 1e-3 |\n| --- | --- | --- | --- | --- |\n",
        clock_name);
    for (const std::string& name : integrators) {
      const std::vector<Point>& c = curves[name];
      const double k = error_time_product(c);
      auto cell = [&](double target) {
        const std::optional<double> t = time_to_reach(c, target);
        return t ? seconds(t) : fmt::format("({:.3g} s by 1/t)", k / target);
      };
      std::cout << fmt::format("| {} | {:.3g} | {:.3g} | {} | {} |\n", name,
                               samples_per_s[name] * 1e-6, k, cell(1e-2), cell(1e-3));
    }
    if (curves.count("naive") && curves.count("nee")) {
      const std::vector<Point>& naive = curves["naive"];
      const std::vector<Point>& nee = curves["nee"];
      const double t = std::min(naive.back().time_s, nee.back().time_s);
      const std::optional<double> e_naive = error_at(naive, t), e_nee = error_at(nee, t);
      if (e_naive && e_nee) {
        std::cout << fmt::format(
            "\nequal time, {:.3g} s: naive relMSE {:.3e}, nee {:.3e}: naive's error is {:.1f}x "
            "NEE's; "
            "naive needs about {:.1f}x NEE's time for the same error (relMSE x time {:.3g} vs "
            "{:.3g})\n",
            t, *e_naive, *e_nee, *e_naive / *e_nee,
            error_time_product(naive) / error_time_product(nee), error_time_product(naive),
            error_time_product(nee));
      }
    }

    LogLogPlot plot;
    plot.title = fmt::format("{}: relMSE against render time ({}x{}, {} threads)",
                             fs::path(scene_path).parent_path().filename().string(),
                             scene.film.width, scene.film.height, threads);
    plot.x_label = clock == Clock::kCpu ? "render time (CPU s, all threads)" : "render time (s)";
    plot.y_label = "relMSE";
    const std::map<std::string, PlotColor> colours{
        {"naive", {200, 50, 40}}, {"nee", {40, 140, 60}}, {"mis", {40, 80, 200}}};
    for (const std::string& name : integrators) {
      PlotSeries s{name, colours.count(name) ? colours.at(name) : PlotColor{0, 0, 0}, {}};
      for (const Point& p : curves[name]) s.points.emplace_back(p.time_s, p.rel_mse);
      plot.series.push_back(std::move(s));
    }
    if (!curves.empty()) {
      const Point& p = curves[integrators.front()].front();
      plot.slope_line = SlopeLine{"1/t", {p.time_s, p.rel_mse}};
    }
    write_plot_png(plot, plot_path);
    std::cout << fmt::format("\nwrote {} and {}/<integrator>.csv\n", plot_path, out_dir);
  } catch (const std::exception& e) {
    std::cerr << "convergence: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
