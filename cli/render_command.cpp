// `rayfarm render`: renders a scene on this machine, exactly as the farm would.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>

#include <fmt/format.h>

#include "cli/commands.h"
#include "common/image/film_output.h"
#include "common/scene/parser.h"
#include "common/util/log.h"
#include "worker/renderer.h"

namespace rayfarm::cli {
namespace {

struct RenderArgs {
  std::string scene;
  std::string output;
  std::optional<uint32_t> spp, max_depth, tile, pass_spp;
  std::optional<uint64_t> seed;
  std::optional<std::string> integrator;
  uint32_t threads = 0;
};

// A progress bar on a terminal; a plain line per pass otherwise.
class ProgressReporter {
 public:
  ProgressReporter() : tty_(isatty(STDERR_FILENO) != 0) {}

  void update(const RenderProgress& p) {
    const double fraction = p.units_total ? double(p.units_done) / double(p.units_total) : 1.0;
    if (tty_) {
      const int width = 30, filled = static_cast<int>(fraction * width);
      const double eta = fraction > 0 ? p.seconds * (1.0 - fraction) / fraction : 0.0;
      std::fprintf(stderr, "\r[%s%s] %5.1f%%  pass %u/%u  %.1fs elapsed, ETA %.1fs ",
                   std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(),
                   100.0 * fraction, p.passes_done + (p.units_done < p.units_total ? 1 : 0),
                   p.passes_total, p.seconds, eta);
      if (p.units_done == p.units_total) std::fputc('\n', stderr);
    } else if (p.passes_done != last_pass_ || p.units_done == p.units_total) {
      last_pass_ = p.passes_done;
      std::fprintf(stderr, "progress: %.1f%% (%llu/%llu units), %.1fs\n", 100.0 * fraction,
                   static_cast<unsigned long long>(p.units_done),
                   static_cast<unsigned long long>(p.units_total), p.seconds);
    }
  }

 private:
  bool tty_;
  uint32_t last_pass_ = 0;
};

int run_render(const RenderArgs& args) {
  auto log = get_logger("render");
  Scene scene = load_scene(args.scene);
  for (const std::string& w : scene.warnings) log->warn("{}", w);

  RenderSettings settings = scene.render;
  if (args.spp) settings.spp = *args.spp;
  if (args.max_depth) settings.max_depth = *args.max_depth;
  if (args.seed) settings.seed = *args.seed;
  if (args.integrator) settings.integrator = *parse_integrator(*args.integrator);
  if (settings.spp == 0) throw std::invalid_argument("--spp must be at least 1");

  LocalRenderOptions options;
  options.threads = args.threads;
  options.tile_size = args.tile.value_or(64);
  options.pass_spp = args.pass_spp.value_or(0);
  if (options.tile_size == 0) throw std::invalid_argument("--tile must be at least 1");

  const auto start = std::chrono::steady_clock::now();
  Renderer renderer(scene, settings);
  log->info("{}: {}x{}, {} spp, seed {}; {}", args.scene, scene.film.width, scene.film.height,
            settings.spp, settings.seed, renderer.plan());
  ProgressReporter reporter;
  options.on_progress = [&](const RenderProgress& p, const Film&) { reporter.update(p); };
  const Film film = render_local(renderer, options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  write_film(args.output, film,
             {{"rayfarm:integrator", integrator_name(settings.integrator)},
              {"rayfarm:seed", std::to_string(settings.seed)},
              {"rayfarm:max_depth", std::to_string(settings.max_depth)},
              {"rayfarm:scene", std::filesystem::path(args.scene).filename().string()}});

  const double samples = double(scene.film.width) * scene.film.height * settings.spp;
  std::cout << fmt::format("wrote {} and {}\n", args.output, preview_path(args.output).string());
  std::cout << fmt::format("time {:.3f} s, {:.3f} Msamples/s, {:.3f} Mrays/s, {:.2f} spp/s at {}x{}\n",
                           seconds, samples / seconds * 1e-6, double(film.rays()) / seconds * 1e-6,
                           settings.spp / seconds, scene.film.width, scene.film.height);
  if (film.nonfinite() > 0) {
    log->warn("{} samples were NaN, infinite or out of range and were dropped", film.nonfinite());
  }
  return 0;
}

}  // namespace

void add_render_command(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand("render", "Render a scene on this machine to an EXR (+ PNG preview)");
  cmd->add_option("scene", args->scene, "Scene file (JSON)")->required();
  cmd->add_option("-o,--output", args->output, "Output EXR file")->required();
  cmd->add_option("--spp", args->spp, "Samples per pixel (default: the scene's)");
  cmd->add_option("--integrator", args->integrator, "naive, nee or mis (default: the scene's)")
      ->check(CLI::IsMember({"naive", "nee", "mis"}));
  cmd->add_option("--max-depth", args->max_depth, "Most scattering vertices per path");
  cmd->add_option("--seed", args->seed, "Random seed (default: the scene's)");
  cmd->add_option("--threads", args->threads, "Threads (0 = all)")->capture_default_str();
  cmd->add_option("--tile", args->tile, "Tile size in pixels (default 64); does not change the image");
  cmd->add_option("--pass-spp", args->pass_spp, "Samples per pass (default: automatic); does not change the image");
  cmd->callback([args, &exit_code] {
    try {
      exit_code = run_render(*args);
    } catch (const std::exception& e) {
      std::cerr << "rayfarm render: error: " << e.what() << "\n";
      exit_code = 1;
    }
  });
}

}  // namespace rayfarm::cli
