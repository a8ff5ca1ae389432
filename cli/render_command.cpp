// `rayfarm render`: renders a scene on this machine, exactly as the farm would.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>

#include <fmt/format.h>

#include "cli/commands.h"
#include "cli/film_option.h"
#include "cli/frames_option.h"
#include "cli/output_path.h"
#include "cli/sampling_options.h"
#include "cli/scene_option.h"
#include "cli/stop_options.h"
#include "common/image/film_output.h"
#include "common/image/png.h"
#include "common/limits.h"
#include "common/protocol/version.h"
#include "common/report/error_tracker.h"
#include "common/scene/animation.h"
#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "common/util/log.h"
#include "renderer/renderer.h"

namespace rayfarm::cli {
namespace {

struct RenderArgs {
  SceneArgs source;
  std::string output;
  std::optional<uint32_t> spp, tile, pass_spp;
  SamplingArgs sampling;
  std::optional<uint64_t> seed;
  std::optional<std::string> integrator;
  float clamp = 0.f;
  uint32_t threads = 0;
  StopArgs stop;
  bool error_record = false;  // --error-record
  FilmArgs film;
  std::optional<int64_t> frame;       // --frame N
  std::optional<std::string> frames;  // --frames A-B[:STEP]
};

/// "out.exr" -> "out.error.csv" and "out.error.png": the error record beside the image.
std::filesystem::path error_csv_path(const std::filesystem::path& exr) {
  std::filesystem::path p = exr;
  return p.replace_extension(".error.csv");
}
std::filesystem::path error_plot_path(const std::filesystem::path& exr) {
  std::filesystem::path p = exr;
  return p.replace_extension(".error.png");
}

// A progress bar on a terminal; a plain line per pass otherwise.
class ProgressReporter {
 public:
  ProgressReporter() : tty_(isatty(STDERR_FILENO) != 0) {}

  /// `row` is set when a round of passes has just completed (its error figures are new).
  void update(const RenderProgress& p, const ErrorRow* row) {
    const bool last = p.reason != StopReason::kRunning;
    const double fraction = last               ? 1.0
                            : p.units_released ? double(p.units_done) / double(p.units_released)
                                               : 0.0;
    if (row && std::isfinite(row->est_rel_mse))
      error_ = fmt::format("relMSE~{:.3g}", row->est_rel_mse);
    if (tty_) {
      const int width = 30, filled = static_cast<int>(fraction * width);
      std::fprintf(stderr, "\r[%s%s] %5.1f%%  pass %u/%u  %.1fs  %s ",
                   std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(),
                   100.0 * fraction, std::min(p.rounds_done + (last ? 0 : 1), p.passes_total),
                   p.passes_total, p.seconds, error_.c_str());
      if (last) std::fputc('\n', stderr);
    } else if (row || last) {
      std::fprintf(stderr, "progress: pass %u/%u, %llu/%llu units, %.1fs, %s\n", p.rounds_done,
                   p.passes_total, static_cast<unsigned long long>(p.units_done),
                   static_cast<unsigned long long>(p.units_released), p.seconds, error_.c_str());
    }
  }

 private:
  bool tty_;
  std::string error_ = "relMSE unknown";
};

/// Renders the scene (at `frame` when given) to `output`, whose format is checked.
void render_one(const RenderArgs& args, std::optional<int64_t> frame,
                const std::filesystem::path& output_path, OutputFormat format) {
  auto log = get_logger("render");
  const std::string output = output_path.string();
  Scene scene = args.source.load(SceneImages::kKeep, frame);
  for (const std::string& w : scene.warnings) log->warn("{}", w);
  if (args.film.given()) check_uncropped(scene);
  if (const auto film = args.film.resolve(scene.film)) scene.film = *film;

  RenderSettings settings = scene.render;
  if (args.spp) settings.spp = *args.spp;
  args.sampling.apply(settings);
  if (args.seed) settings.seed = *args.seed;
  if (args.integrator) settings.integrator = *parse_integrator(*args.integrator);
  settings.clamp = args.clamp;
  if (settings.spp == 0) throw std::invalid_argument("--spp must be at least 1");
  const size_t warned = scene.warnings.size();
  args.source.add_motion(scene, settings);  // the poses within an open shutter
  for (size_t i = warned; i < scene.warnings.size(); ++i) log->warn("{}", scene.warnings[i]);
  if (settings.shutter_is_open() && !scene.animation) {
    log->warn("{}: the shutter is open, but the scene is a still{}: nothing moves within it",
              args.source.scene, args.source.is_list() ? " (a list's files are)" : "");
  }

  LocalRenderOptions options;
  options.threads = args.threads;
  options.tile_size = args.tile.value_or(kDefaultTileSize);
  options.pass_spp = args.pass_spp.value_or(0);
  options.stop = args.stop.rules();
  check_stop_rules(options.stop);
  if (options.tile_size == 0) throw std::invalid_argument("--tile must be at least 1");

  std::optional<Image> reference;
  if (args.stop.reference) reference = load_reference(*args.stop.reference, scene.film);
  ErrorTracker tracker(split_tiles(scene.film, options.tile_size), std::move(reference));

  Renderer renderer(scene, settings);
  drop_images(scene);  // the renderer holds its own texels
  log->info("{}{}: {}x{}, {} spp, seed {}; {}", args.source.scene,
            scene.frame ? fmt::format(" frame {}", *scene.frame) : "", scene.film.width,
            scene.film.height, settings.spp, settings.seed, renderer.plan());
  if (options.stop.target_error > 0 || options.stop.time_limit_s > 0) {
    log->info("stopping rules: {} spp{}{}", settings.spp,
              options.stop.target_error > 0
                  ? fmt::format(", target relMSE {:g} ({})", options.stop.target_error,
                                options.stop.adaptive ? "per tile" : "whole passes")
                  : "",
              options.stop.time_limit_s > 0
                  ? fmt::format(", time limit {:g} s", options.stop.time_limit_s)
                  : "");
  }
  ProgressReporter reporter;
  std::vector<ErrorRow> rows;  // the error record: a row per round of passes, and the final one
  uint32_t rounds_recorded = 0;
  uint64_t samples_recorded = 0;
  RenderProgress final_progress;
  options.on_progress = [&](const RenderProgress& p, const Film& film) {
    // A row per round of passes, and one for the final image.
    const ErrorRow* row = nullptr;
    const bool last = p.reason != StopReason::kRunning;
    if (p.rounds_done > rounds_recorded || (last && film.pixel_samples() > samples_recorded)) {
      rounds_recorded = p.rounds_done;
      samples_recorded = film.pixel_samples();
      rows.push_back(tracker.record(film, p.seconds));
      row = &rows.back();
    }
    reporter.update(p, row);
    final_progress = p;
  };
  const Film film = render_local(renderer, options);
  const double seconds = final_progress.seconds;
  if (rows.empty()) {
    // Only a time limit shorter than the first unit gets here: nothing to estimate or write.
    throw std::runtime_error(fmt::format(
        "the time limit ({:g} s) ended the render before its first unit was done; nothing written",
        options.stop.time_limit_s));
  }
  const ErrorRow& last = rows.back();

  std::map<std::string, std::string> attributes{
      {"rayfarm:integrator", integrator_name(settings.integrator)},
      {"rayfarm:seed", std::to_string(settings.seed)},
      {"rayfarm:max_depth", depth_name(settings.max_depth)},
      {"rayfarm:sampler", sampler_name(settings.sampler)},
      {"rayfarm:roulette", roulette_name(settings.roulette)},
      {"rayfarm:roulette_depth", std::to_string(settings.roulette_depth)},
      {"rayfarm:scene", std::filesystem::path(args.source.scene).filename().string()},
      {"rayfarm:stop", stop_reason_name(final_progress.reason)},
      {"rayfarm:est_rel_mse", fmt::format("{:.6g}", last.est_rel_mse)}};
  if (settings.shutter_is_open()) attributes["rayfarm:shutter"] = shutter_attribute(settings);
  if (settings.clamp > 0) attributes["rayfarm:clamp"] = fmt::format("{:g}", settings.clamp);
  if (scene.frame) attributes["rayfarm:frame"] = std::to_string(*scene.frame);
  std::string wrote = output;
  if (format == OutputFormat::kExr) {
    write_film(output, film, attributes);
    wrote += " and " + preview_path(output).string();
  } else {
    write_png_preview(output, film_to_image(film, attributes));
  }
  // The error record goes beside an EXR (the render's full result); beside a PNG, which is asked
  // for as a picture alone, only when asked for: --error-record, or a target error or a
  // reference, which are about the error.
  const bool record = format == OutputFormat::kExr || args.error_record ||
                      options.stop.target_error > 0 || tracker.has_reference();
  if (record) {
    write_error_csv(error_csv_path(output), rows);
    write_error_plot(
        error_plot_path(output), rows,
        fmt::format("{} ({}, {})", std::filesystem::path(args.source.scene).filename().string(),
                    integrator_name(settings.integrator),
                    tracker.has_reference() ? "estimated and measured" : "estimated"));
  }

  const double samples = static_cast<double>(film.pixel_samples());
  const double spp_mean = samples / (double(scene.film.width) * scene.film.height);
  if (record) {
    std::cout << fmt::format("wrote {}; error record {} and {}\n", wrote,
                             error_csv_path(output).string(), error_plot_path(output).string());
  } else {
    std::cout << fmt::format("wrote {}\n", wrote);
  }
  std::cout << fmt::format(
      "time {:.3f} s, {:.3f} Msamples/s, {:.3f} Mrays/s, {:.2f} spp/s at {}x{}\n", seconds,
      samples / seconds * 1e-6, double(film.rays()) / seconds * 1e-6, spp_mean / seconds,
      scene.film.width, scene.film.height);
  std::cout << fmt::format(
      "stopped: {}; {:.1f} spp mean ({} to {} per pixel){}\n",
      stop_reason_name(final_progress.reason), spp_mean, film.min_spp(), film.max_spp(),
      options.stop.target_error > 0
          ? fmt::format(", {}/{} tiles converged", final_progress.tiles_converged,
                        final_progress.tiles_total)
          : "");
  std::cout << (std::isfinite(last.est_rel_mse)
                    ? fmt::format("estimated relMSE {:.4g}, RMSE {:.4g}", last.est_rel_mse,
                                  last.est_rmse)
                    : std::string("estimated relMSE -"));
  if (last.ref_rel_mse) {
    std::cout << fmt::format("; against {}: relMSE {:.4g}, RMSE {:.4g}, MAE {:.4g}, max {:.4g}",
                             *args.stop.reference, *last.ref_rel_mse, *last.ref_rmse, *last.ref_mae,
                             *last.ref_max);
  }
  std::cout << "\n";
  if (film.nonfinite() > 0) {
    log->warn("{} samples were NaN, infinite or out of range and were dropped", film.nonfinite());
  }
}

int run_render(const RenderArgs& args) {
  const OutputFormat format = check_output_path(args.output);  // before any work
  get_logger("render")->info("{}", protocol::kBuildVersion);
  if (!args.frames) {
    // One image: a '#' or '%d' in the name takes the frame number.
    const bool pattern = args.frame && has_frame_pattern(args.output);
    render_one(
        args, args.frame,
        pattern ? frame_output_path(args.output, *args.frame) : std::filesystem::path(args.output),
        format);
    return 0;
  }
  // A sequence: every check before the first frame renders.
  const FrameList frames =
      check_frames_option(*args.frames, args.source, args.stop.reference.has_value());
  (void)frame_output_path(args.output, frames.first);  // a malformed '%' is refused now
  const auto start = std::chrono::steady_clock::now();
  for (int64_t i = 0; i < frames.count(); ++i) {
    const int64_t frame = frames.at(i);
    std::cout << fmt::format("frame {} ({} of {})\n", frame, i + 1, frames.count());
    render_one(args, frame, frame_output_path(args.output, frame), format);
  }
  std::cout << fmt::format(
      "rendered {} frames ({}) in {:.3f} s\n", frames.count(), frame_list_name(frames),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return 0;
}

}  // namespace

void add_render_command(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd =
      app.add_subcommand("render", "Render a scene on this machine to an EXR (+ PNG preview)");
  cmd->add_option("scene", args->source.scene,
                  "Scene file: JSON, glTF 2.0 (.gltf, .glb) or Mitsuba 3 XML (.xml)")
      ->required();
  add_scene_options(cmd, args->source);
  cmd->add_option("-o,--output", args->output,
                  "Output: x.exr (float EXR, and an sRGB preview x.png beside it) or x.png (the "
                  "preview alone); checked before rendering")
      ->required();
  cmd->add_option("--spp", args->spp, "Samples per pixel (default: the scene's)");
  cmd->add_option("--integrator", args->integrator, "naive, nee or mis (default: the scene's)")
      ->check(CLI::IsMember({"naive", "nee", "mis"}));
  add_sampling_options(cmd, args->sampling);
  cmd->add_option("--seed", args->seed, "Random seed (default: the scene's)");
  add_clamp_option(cmd, args->clamp);
  cmd->add_option("--threads", args->threads, "Threads (0 = all)")->capture_default_str();
  cmd->add_option("--tile", args->tile,
                  "Tile size in pixels (default " + std::to_string(kDefaultTileSize) +
                      "); does not change the image");
  cmd->add_option("--pass-spp", args->pass_spp,
                  "Samples per pass (default: automatic); does not change the image");
  add_film_options(cmd, args->film);
  add_stop_options(cmd, args->stop,
                   "Reference EXR: the error against it is measured at every pass");
  cmd->add_flag("--error-record", args->error_record,
                "Write the error record beside a PNG output too: x.error.csv (time, spp, "
                "estimated and measured relMSE per pass) and its plot x.error.png (always beside "
                "an EXR, and with --target-error or --reference)");
  CLI::Option* frame =
      cmd->add_option("--frame", args->frame,
                      "Animated scenes, or a list of scene files (frame_####.json): the frame to "
                      "render (default: the first); a '#' run or "
                      "%04d in the output's name takes its number");
  cmd->add_option("--frames", args->frames,
                  "Animated scenes, or a list of scene files (frame_####.json): frames A-B[:STEP], "
                  "one image each; the output's '#' run or "
                  "%04d takes the frame number (default: .NNNN before the extension)")
      ->excludes(frame);
  cmd->callback([args, &exit_code] {
    try {
      exit_code = run_render(*args);
    } catch (const CLI::ParseError&) {
      throw;  // a usage error found after parsing (main.cpp: exit 2, with the usage line)
    } catch (const std::exception& e) {
      std::cerr << "rayfarm render: error: " << e.what() << "\n";
      exit_code = 1;
    }
  });
}

}  // namespace rayfarm::cli
