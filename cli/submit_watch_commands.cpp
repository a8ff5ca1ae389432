// submit and watch: a job sent to the master, and its progress followed until it ends (submit
// --wait is submit then watch).
#include <unistd.h>

#include <chrono>
#include <iostream>
#include <optional>
#include <string>
#include <thread>

#include <fmt/format.h>

#include "cli/farm_client.h"
#include "cli/farm_commands.h"
#include "cli/farm_output.h"
#include "cli/film_option.h"
#include "cli/frames_option.h"
#include "cli/output_path.h"
#include "cli/sampling_options.h"
#include "cli/scene_option.h"
#include "cli/stop_options.h"
#include "common/bundle/bundle.h"
#include "common/limits.h"
#include "common/protocol/convert.h"
#include "common/scene/animation.h"
#include "common/scene/frames.h"
#include "common/scene/parser.h"
#include "common/util/read_file.h"

namespace rayfarm::cli {
namespace fs = std::filesystem;
using protocol::encode;

namespace {

constexpr auto kWatchPeriod = std::chrono::milliseconds{500};

/// Shows the job's progress until it ends (a live line on a terminal, plain lines otherwise, or
/// with `json` one status object per line whenever it changes); returns the exit code for its
/// final state.
int watch_job(StatusPoller& poller, const std::string& job, bool json) {
  const bool tty = !json && isatty(STDOUT_FILENO) != 0;
  catch_interrupts();
  std::string last_line;
  auto last_print = std::chrono::steady_clock::now() - std::chrono::hours(1);
  while (true) {
    const wire::JobStatus st = poller.status(job);
    const auto now = std::chrono::steady_clock::now();
    if (json) {
      // A line when the job moved (units, passes, state, paused, priority), not for the clock
      // alone.
      const std::string key =
          fmt::format("{}/{}/{}/{}/{}/{}", static_cast<int>(st.state()), st.units_done(),
                      st.passes_done(), st.units_leased(), st.paused(), st.priority());
      if (key != last_line) print_json(status_json(st));
      last_line = key;
    } else {
      const std::string line = progress_line(for_people(st));
      if (tty) {
        std::cout << "\r\033[K" << line << std::flush;
      } else if (st.passes_done() != 0 && line != last_line &&
                 (now - last_print >= std::chrono::seconds(2) || finished(st.state()))) {
        std::cout << line << "\n" << std::flush;
        last_print = now;
      } else if (last_line.empty() || finished(st.state())) {
        std::cout << line << "\n" << std::flush;
        last_print = now;
      }
      last_line = line;
    }
    if (finished(st.state())) {
      if (tty) std::cout << "\n";
      if (st.state() == wire::JOB_CANCELLED) {
        std::cerr << "job " << job << " was cancelled"
                  << (st.error().empty() ? "" : " (" + st.error() + ")") << "\n";
      } else if (st.state() == wire::JOB_FAILED) {
        std::cerr << "job " << job << " failed: " << st.error() << "\n";
      } else if (st.state() == wire::JOB_STATE_UNSPECIFIED) {
        std::cerr << "job " << job << ": " << st.error() << "\n";
        return kExitError;
      }
      return st.state() == wire::JOB_DONE ? 0 : kExitJobUnsuccessful;
    }
    for (auto waited = std::chrono::milliseconds{0}; waited < kWatchPeriod;
         waited += std::chrono::milliseconds{50}) {
      if (interrupted()) {
        if (tty) std::cout << "\n";
        return kExitInterrupted;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds{50});
    }
  }
}

struct SubmitArgs {
  ClientArgs client;
  SceneArgs source;
  std::optional<uint32_t> spp, tile, pass_spp;
  SamplingArgs sampling;
  std::optional<uint64_t> seed;
  std::optional<std::string> integrator;
  std::string name;
  bool wait = false;
  bool json = false;
  int32_t priority = 0;
  bool paused = false;
  float clamp = 0.f;
  std::string output;
  StopArgs stop;
  FilmArgs film;
  std::optional<int64_t> frame;
  std::optional<std::string> frames;  // --frames A-B[:STEP]
};

int run_submit(const SubmitArgs& args) {
  std::optional<OutputFormat> format;
  if (!args.output.empty()) {
    if (!args.wait)
      throw CLI::ValidationError("-o needs --wait: the image is fetched when the job is done");
    format = check_output_path(args.output);  // before the job is sent
  }
  // Frames are checked here (against the scene's animation, or every file of a list of scene
  // files), before anything is sent.
  std::optional<FrameList> frames;
  if (args.frames) {
    frames = check_frames_option(*args.frames, args.source, args.stop.reference.has_value());
  }
  const bool list = args.source.is_list();
  // One frame of a scene is checked against its animation here too, naming the scene the user
  // gave (the master would name the bundle's file, e.g. a glTF camera's wrapper).
  if (!list && args.frame) {
    args.source.check();
    check_frame(args.source.scene, load_scene_animation(args.source.scene), args.frame);
  }
  // A list without frames is refused (load says why); one frame of it must be a still.
  if (list && !frames) (void)args.source.load(SceneImages::kCheckOnly, args.frame);
  std::vector<fs::path> files;
  if (list && frames) {
    for (int64_t i = 0; i < frames->count(); ++i)
      files.push_back(args.source.file_at(frames->at(i)));
  }
  // One frame of a list is the still scene in its file.
  const PackedScene packed = !list    ? args.source.pack()
                             : frames ? pack_scene_list(args.source.scene, files)
                                      : pack_scene(args.source.file_at(*args.frame));
  wire::SubmitJob request;
  protocol::bundle_to_wire(packed.bundle, request.mutable_bundle());
  request.set_scene_path(packed.scene_path);
  // Default name: the scene's folder and file, e.g. "cornell-box/scene.json".
  const fs::path scene_file(args.source.scene);
  const fs::path folder = fs::absolute(scene_file).parent_path().filename();
  std::string name = (folder / scene_file.filename()).generic_string();
  if (args.frame) name += fmt::format(" frame {}", *args.frame);
  request.set_name(!args.name.empty() ? args.name : name);
  if (args.frame && !list) request.set_frame(*args.frame);
  if (frames) *request.mutable_frames() = protocol::frames_to_wire(*frames);
  request.set_priority(args.priority);
  request.set_paused(args.paused);
  wire::JobOverrides* o = request.mutable_overrides();
  if (args.spp) o->set_spp(*args.spp);
  if (args.sampling.max_depth) o->set_max_depth(*parse_depth(*args.sampling.max_depth));
  if (args.sampling.sampler)
    o->set_sampler(protocol::sampler_to_wire(*parse_sampler(*args.sampling.sampler)));
  if (args.sampling.roulette)
    o->set_roulette(protocol::roulette_to_wire(*parse_roulette(*args.sampling.roulette)));
  if (args.sampling.roulette_depth) o->set_roulette_depth(*args.sampling.roulette_depth);
  if (args.sampling.shutter) {
    const auto shutter = *parse_shutter(*args.sampling.shutter);
    o->set_shutter_open(shutter.first);
    o->set_shutter_close(shutter.second);
  }
  if (args.sampling.motion_steps) o->set_motion_steps(*args.sampling.motion_steps);
  if (args.seed) o->set_seed(*args.seed);
  if (args.integrator)
    o->set_integrator(protocol::integrator_to_wire(*parse_integrator(*args.integrator)));
  if (args.tile) o->set_tile_size(*args.tile);
  if (args.pass_spp) o->set_pass_spp(*args.pass_spp);
  o->set_clamp(args.clamp);
  if (args.film.given()) {
    const Scene scene = args.source.load(SceneImages::kCheckOnly,
                                         frames ? std::optional(frames->first) : args.frame);
    check_uncropped(scene);
    const auto film = args.film.resolve(scene.film);
    o->set_width(film->width);
    o->set_height(film->height);
  }
  o->set_target_error(args.stop.target_error);
  o->set_time_limit_s(args.stop.time_limit);
  o->set_no_adaptive(args.stop.no_adaptive);
  o->set_min_passes(args.stop.min_passes);
  if (const auto& reference = args.stop.reference) {
    std::optional<std::string> bytes = try_read_whole_file(*reference);
    if (!bytes) throw std::runtime_error(*reference + ": cannot read the reference");
    if (bytes->empty())
      throw std::runtime_error(*reference + ": the reference is missing or empty");
    request.set_reference_exr(std::move(*bytes));
  }

  std::string job;
  {
    FarmClient client(args.client);
    // A master checking many submissions at once says it is busy: try again, within --timeout.
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(args.client.timeout);
    auto pause = std::chrono::milliseconds{100};
    wire::SubmitReply reply = client.call<wire::SubmitReply>(encode(request));
    while (reply.code() == wire::Error::BUSY &&
           std::chrono::steady_clock::now() + pause < deadline) {
      std::this_thread::sleep_for(pause);
      pause = std::min(pause * 2, std::chrono::milliseconds{2000});
      reply = client.call<wire::SubmitReply>(encode(request));
    }
    if (!reply.error().empty()) throw MasterError("the master rejected the job: " + reply.error());
    job = reply.job_id();
    if (args.json) {
      if (!args.wait) print_json(status_json(query_status(client, job)));
    } else {
      std::cout << job << "\n" << std::flush;
    }
  }
  if (!args.wait) return 0;
  StatusPoller poller(args.client, "submit");
  const int code = watch_job(poller, job, args.json);
  if (args.frames && format && code != kExitInterrupted && code != kExitError) {
    // The frames that are done come home even when others failed or were cancelled.
    try {
      const auto wrote = poller.with_retry([&](FarmClient& client) {
        return fetch_frames(client, job, args.output, *format, std::nullopt);
      });
      for (const std::string& line : wrote) std::cerr << line << "\n";
    } catch (const MasterError& e) {
      if (code == 0) throw;
      std::cerr << e.what() << "\n";
    }
    return code;
  }
  if (code != 0 || !format) return code;
  const std::string wrote = poller.with_retry(
      [&](FarmClient& client) { return fetch_image(client, job, args.output, *format); });
  std::cerr << wrote << "\n";
  return 0;
}

}  // namespace

void add_submit(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<SubmitArgs>();
  CLI::App* cmd = app.add_subcommand("submit", "Submit a scene to a farm; prints the job id");
  cmd->add_option("scene", args->source.scene,
                  "Scene file (JSON, glTF 2.0: .gltf, .glb, or Mitsuba 3 XML: .xml); it and every "
                  "file it uses travel with the job")
      ->required();
  add_scene_options(cmd, args->source);
  add_client_options(cmd, args->client);
  cmd->add_option("--spp", args->spp, "Samples per pixel (default: the scene's)");
  cmd->add_option("--integrator", args->integrator, "naive, nee or mis (default: the scene's)")
      ->check(CLI::IsMember({"naive", "nee", "mis"}));
  add_sampling_options(cmd, args->sampling);
  cmd->add_option("--seed", args->seed, "Random seed (default: the scene's)");
  cmd->add_option("--tile", args->tile,
                  "Tile size in pixels (default " + std::to_string(kDefaultTileSize) +
                      "); does not change the image")
      ->check(CLI::Range(1u, 4096u));
  cmd->add_option("--pass-spp", args->pass_spp,
                  "Samples per pass (default: automatic); does not change the image")
      ->check(CLI::PositiveNumber);
  add_film_options(cmd, args->film);
  add_clamp_option(cmd, args->clamp);
  add_stop_options(
      cmd, args->stop,
      "Reference EXR sent with the job: the error against it is measured at every pass");
  cmd->add_option("--name", args->name, "Job name (default: the scene file's name)");
  CLI::Option* frame =
      cmd->add_option("--frame", args->frame,
                      "Animated scenes, or a list of scene files (frame_####.json): the frame to "
                      "render (default: the scene's first)");
  cmd->add_option("--frames", args->frames,
                  "Animated scenes, or a list of scene files (frame_####.json): a sequence of "
                  "frames A-B[:STEP], one job each, rendered in "
                  "order; with --wait -o, every frame is fetched ('#' or %04d in the name)")
      ->excludes(frame);
  cmd->add_option("--priority", args->priority,
                  "Higher runs first, from " + std::to_string(kMinPriority) + " to " +
                      std::to_string(kMaxPriority) +
                      " (default 0; jobs of equal priority share the workers; a master with keys "
                      "may cap what a key that is not an admin can ask for)")
      ->check(CLI::Range(kMinPriority, kMaxPriority));
  cmd->add_flag("--paused", args->paused,
                "Accept the job paused: no unit is handed out until `rayfarm resume JOB`");
  cmd->add_flag("--wait", args->wait,
                "Show progress until the job ends, riding out master restarts within --timeout; "
                "exit 0 only when it is done");
  cmd->add_option("-o,--output", args->output,
                  "With --wait: fetch the image when the job is done (x.exr and x.png, or x.png "
                  "alone); the path is checked before the job is sent");
  cmd->add_flag("--json", args->json,
                "Print the job's status as JSON (with --wait: one object per line as it changes)");
  cmd->callback(
      [args, &exit_code] { exit_code = guarded("submit", [&] { return run_submit(*args); }); });
}

void add_watch(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "watch",
      "Follow a job's progress until it ends (Ctrl-C to stop watching); rides out a master "
      "restart within --timeout");
  cmd->add_option("job", *job, "Job id")->required();
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "One JSON status object per line, whenever the job moves");
  cmd->callback([args, job, json, &exit_code] {
    exit_code = guarded("watch", [&] {
      StatusPoller poller(*args, "watch");
      return watch_job(poller, *job, *json);
    });
  });
}

}  // namespace rayfarm::cli
