// The farm's client commands: submit, status, list, watch, cancel, fetch. Each talks to the
// master's client endpoint over one DEALER socket: Hello, then one request and its reply, every
// wait bounded by --timeout so that an unreachable master is an error (exit 3), never a hang.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <thread>

#include <fmt/format.h>

#include "cli/commands.h"
#include "cli/farm_client.h"
#include "cli/stop_options.h"
#include "common/bundle/bundle.h"
#include "common/image/film_output.h"
#include "common/net/keys.h"
#include "common/net/peer_options.h"
#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/parser.h"
#include "common/util/atomic_file.h"

namespace rayfarm::cli {
namespace {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;
namespace wire = rayfarm::wire;
using protocol::encode;

constexpr int kExitError = 1;
constexpr int kExitJobUnsuccessful = 2;  // the job failed or was cancelled
constexpr int kExitUnreachable = 3;
constexpr int kExitRefused = 4;  // the master did not admit this client (key, security)
constexpr int kExitInterrupted = 130;
constexpr auto kWatchPeriod = std::chrono::milliseconds{500};

/// The master did not answer in time.
class Unreachable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The master did not admit this client: its key is not on the allow-list, or the two sides'
/// security does not match.
class NotAdmitted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The master answered with an error (or a refusal); what() is its message.
class MasterError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

std::atomic<bool> g_interrupted{false};
void on_sigint(int) { g_interrupted.store(true); }

std::string default_master() {
  const char* env = std::getenv("RAYFARM_MASTER");
  return env && *env ? env : "tcp://localhost:5556";
}

struct ClientArgs {
  std::string master = default_master();
  double timeout = 10.0;
  net::PeerKeyOptions keys;
};

void add_client_options(CLI::App* cmd, ClientArgs& args) {
  cmd->add_option("--master", args.master, "the master's client endpoint (env RAYFARM_MASTER)")
      ->capture_default_str();
  cmd->add_option("--timeout", args.timeout, "seconds to wait for the master")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  net::add_peer_key_options(*cmd, args.keys, "client");
}

/// The socket's CURVE settings from the arguments; throws naming what is missing.
net::Curve client_curve(const ClientArgs& args) {
  if (args.keys.insecure) {
    if (!net::is_loopback_endpoint(args.master)) {
      throw std::runtime_error("--insecure is allowed only with a master on loopback, and " +
                               args.master +
                               " is not: give --key and --master-key (or RAYFARM_KEY and "
                               "RAYFARM_MASTER_KEY)");
    }
    std::cerr << "rayfarm: warning: INSECURE: no authentication and no encryption to "
              << args.master << "\n";
  }
  return net::peer_curve(args.keys, "this client");
}

/// One connection to the master's client endpoint.
class FarmClient {
 public:
  explicit FarmClient(const ClientArgs& args)
      : endpoint_(args.master),
        timeout_(std::chrono::duration_cast<std::chrono::milliseconds>(
            std::chrono::duration<double>(args.timeout))),
        socket_(args.master, net::kDefaultMaxMessageBytes, client_curve(args)) {
    wire::Hello hello;
    hello.set_role(wire::ROLE_CLIENT);
    hello.set_name("rayfarm-cli");
    hello.set_build(protocol::kBuildVersion);
    call<wire::Welcome>(encode(std::move(hello)));
  }

  /// Sends a request and waits for a reply of type Reply. Throws Unreachable after the timeout
  /// and MasterError on an Error or Refusal.
  template <class Reply>
  Reply call(const net::Frames& request) {
    const auto deadline = std::chrono::steady_clock::now() + timeout_;
    // A send fails while no connection can take the message (e.g. one refused in its handshake):
    // try again until the deadline, saying why as soon as the handshake tells.
    while (!socket_.send(request)) {
      check_admitted();
      if (std::chrono::steady_clock::now() >= deadline) throw Unreachable(unreachable_message());
      if (g_interrupted.load()) throw MasterError("interrupted");
      std::this_thread::sleep_for(std::chrono::milliseconds{20});
    }
    while (true) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) throw Unreachable(unreachable_message());
      auto frames = socket_.receive(std::min(left, std::chrono::milliseconds{100}));
      if (!frames) {
        if (g_interrupted.load()) throw MasterError("interrupted");
        check_admitted();
        continue;
      }
      protocol::Decoded msg = protocol::decode(*frames);
      if (const auto* refusal = msg.as<wire::Refusal>()) throw MasterError(refusal->reason());
      if (const auto* error = msg.as<wire::Error>()) throw MasterError(error->message());
      if (const auto* reply = msg.as<Reply>()) return *reply;
      throw MasterError("unexpected reply " + msg.type + " from the master");
    }
  }

 private:
  std::string endpoint_;
  std::chrono::milliseconds timeout_;
  net::Dealer socket_;

  /// Throws NotAdmitted when the master refused this client's key or security.
  void check_admitted() {
    const net::HandshakeStatus hs = socket_.handshake();
    if (hs.state == net::Handshake::kRefused || hs.state == net::Handshake::kFailed) {
      throw NotAdmitted(
          fmt::format("the master at {} did not let this client in: {}", endpoint_, hs.detail));
    }
  }

  /// Why nothing came back: the handshake's state says whether a connection was made at all.
  std::string unreachable_message() {
    const net::HandshakeStatus hs = socket_.handshake();
    std::string why;
    if (hs.state == net::Handshake::kDropped) {
      why = "the master did not answer: " + hs.detail;
    } else if (hs.state == net::Handshake::kSucceeded) {
      why =
          "the master did not answer in time (it is connected but busy, or the message was "
          "too large for it)";
    } else {
      why =
          "the master did not answer (is it running there? if it is, the key may be wrong: "
          "check --master-key and --key)";
    }
    return fmt::format("cannot reach master at {} within {:g} s: {}", endpoint_,
                       timeout_.count() / 1000.0, why);
  }
};

/// Runs `body`, turning the farm's failures into messages and exit codes.
template <class Body>
int guarded(const char* command, Body&& body) {
  try {
    return body();
  } catch (const Unreachable& e) {
    std::cerr << "rayfarm " << command << ": error: " << e.what() << "\n";
    return kExitUnreachable;
  } catch (const NotAdmitted& e) {
    std::cerr << "rayfarm " << command << ": error: " << e.what() << "\n";
    return kExitRefused;
  } catch (const std::exception& e) {
    if (g_interrupted.load()) return kExitInterrupted;
    std::cerr << "rayfarm " << command << ": error: " << e.what() << "\n";
    return kExitError;
  }
}

std::string format_duration(double seconds) {
  if (seconds < 0) return "?";
  if (seconds < 60) return fmt::format("{:.1f} s", seconds);
  if (seconds < 3600)
    return fmt::format("{}m{:02}s", static_cast<int>(seconds) / 60, static_cast<int>(seconds) % 60);
  return fmt::format("{}h{:02}m", static_cast<int>(seconds) / 3600,
                     (static_cast<int>(seconds) / 60) % 60);
}

std::string format_rate(double samples_per_second) {
  if (samples_per_second >= 1e6) return fmt::format("{:.2f} Msamples/s", samples_per_second / 1e6);
  if (samples_per_second >= 1e3) return fmt::format("{:.1f} ksamples/s", samples_per_second / 1e3);
  return fmt::format("{:.0f} samples/s", samples_per_second);
}

double percent(const wire::JobStatus& st) {
  return st.units_total()
             ? 100.0 * static_cast<double>(st.units_done()) / static_cast<double>(st.units_total())
             : 0.0;
}

bool finished(wire::JobState state) {
  return state == wire::JOB_DONE || state == wire::JOB_FAILED || state == wire::JOB_CANCELLED;
}

std::string progress_line(const wire::JobStatus& st) {
  std::string line = fmt::format(
      "{} {:<9} pass {}/{}  {}/{} spp  {:5.1f}%", st.job_id(), protocol::job_state_name(st.state()),
      st.passes_done(), st.passes_total(), st.spp_done(), st.settings().spp(), percent(st));
  if (st.spp_mean() >= st.spp_done() + 1.0) line += fmt::format(" (mean {:.0f})", st.spp_mean());
  if (st.est_rel_mse() >= 0) line += fmt::format("  relMSE {:.3g}", st.est_rel_mse());
  if (st.ref_rel_mse() >= 0) line += fmt::format(" (measured {:.3g})", st.ref_rel_mse());
  if (st.state() == wire::JOB_RUNNING) {
    line += fmt::format("  {}  ETA {}  workers {} busy/{}", format_rate(st.samples_per_second()),
                        format_duration(st.eta_seconds()), st.workers_busy(), st.workers_total());
  } else if (st.state() == wire::JOB_DONE) {
    line += fmt::format("  in {} ({})", format_duration(st.elapsed_seconds()), st.stop_reason());
  }
  return line;
}

const char* integrator_label(wire::Integrator value) {
  try {
    return integrator_name(protocol::integrator_from_wire(value));
  } catch (const protocol::ProtocolError&) {
    return "unknown integrator";
  }
}

void print_status(const wire::JobStatus& st) {
  std::cout << fmt::format("job        {} ({})\n", st.job_id(), st.name());
  std::cout << fmt::format("state      {}\n", protocol::job_state_name(st.state()));
  if (!st.error().empty()) std::cout << fmt::format("error      {}\n", st.error());
  std::cout << fmt::format("image      {}x{}, {} spp, {}, max depth {}, seed {}\n", st.width(),
                           st.height(), st.settings().spp(),
                           integrator_label(st.settings().integrator()), st.settings().max_depth(),
                           st.settings().seed());
  std::cout << fmt::format(
      "work       tiles of {} px, passes of {} spp: {}/{} units ({:.1f}%), {} leased\n",
      st.tile_size(), st.pass_spp(), st.units_done(), st.units_total(), percent(st),
      st.units_leased());
  std::cout << fmt::format("progress   pass {}/{}, {}/{} spp, {:.1f} spp mean\n", st.passes_done(),
                           st.passes_total(), st.spp_done(), st.settings().spp(), st.spp_mean());
  if (st.est_rel_mse() >= 0 || st.ref_rel_mse() >= 0) {
    std::cout << fmt::format(
        "error      estimated relMSE {}{}\n",
        st.est_rel_mse() >= 0 ? fmt::format("{:.4g}", st.est_rel_mse()) : "unknown",
        st.ref_rel_mse() >= 0 ? fmt::format(", measured against the reference {:.4g}",
                                            st.ref_rel_mse())
                              : "");
  }
  if (st.tiles_converged() > 0) {
    std::cout << fmt::format("tiles      {}/{} converged\n", st.tiles_converged(), st.tiles_total());
  }
  if (!st.stop_reason().empty()) std::cout << fmt::format("stopped    {}\n", st.stop_reason());
  std::cout << fmt::format("time       {} elapsed, ETA {}, {}\n",
                           format_duration(st.elapsed_seconds()), format_duration(st.eta_seconds()),
                           format_rate(st.samples_per_second()));
  std::cout << fmt::format("workers    {} busy on this job, {} connected\n", st.workers_busy(),
                           st.workers_total());
}

void print_table(const wire::JobList& list) {
  if (list.jobs().empty()) {
    std::cout << "no jobs\n";
    return;
  }
  std::cout << fmt::format("{:<8} {:<24} {:<9} {:>7} {:>11} {:>11} {:>10}\n", "JOB", "NAME",
                           "STATE", "DONE", "SPP", "SIZE", "ELAPSED");
  for (const auto& st : list.jobs()) {
    std::cout << fmt::format("{:<8} {:<24} {:<9} {:>6.1f}% {:>11} {:>11} {:>10}\n", st.job_id(),
                             st.name().substr(0, 24), protocol::job_state_name(st.state()),
                             percent(st), fmt::format("{}/{}", st.spp_done(), st.settings().spp()),
                             fmt::format("{}x{}", st.width(), st.height()),
                             format_duration(st.elapsed_seconds()));
  }
}

wire::JobStatus query_status(FarmClient& client, const std::string& job) {
  wire::StatusRequest request;
  request.set_job_id(job);
  return client.call<wire::JobStatus>(encode(std::move(request)));
}

/// Shows a live progress line until the job ends; returns the exit code for its final state.
int watch_job(FarmClient& client, const std::string& job) {
  const bool tty = isatty(STDOUT_FILENO) != 0;
  std::signal(SIGINT, on_sigint);
  std::string last_line;
  auto last_print = std::chrono::steady_clock::now() - std::chrono::hours(1);
  while (true) {
    const wire::JobStatus st = query_status(client, job);
    const std::string line = progress_line(st);
    const auto now = std::chrono::steady_clock::now();
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
    if (finished(st.state())) {
      if (tty) std::cout << "\n";
      if (!st.error().empty()) std::cerr << "job " << job << " failed: " << st.error() << "\n";
      return st.state() == wire::JOB_DONE ? 0 : kExitJobUnsuccessful;
    }
    for (auto waited = std::chrono::milliseconds{0}; waited < kWatchPeriod;
         waited += std::chrono::milliseconds{50}) {
      if (g_interrupted.load()) {
        if (tty) std::cout << "\n";
        return kExitInterrupted;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds{50});
    }
  }
}

// --- Commands ---

struct SubmitArgs {
  ClientArgs client;
  std::string scene;
  std::optional<uint32_t> spp, max_depth, tile, pass_spp;
  std::optional<uint64_t> seed;
  std::optional<std::string> integrator;
  std::string name;
  bool wait = false;
  StopArgs stop;
};

int run_submit(const SubmitArgs& args) {
  const PackedScene packed = pack_scene(args.scene);
  wire::SubmitJob request;
  protocol::bundle_to_wire(packed.bundle, request.mutable_bundle());
  request.set_scene_path(packed.scene_path);
  // Default name: the scene's folder and file, e.g. "cornell-box/scene.json".
  const fs::path scene_file(args.scene);
  const fs::path folder = fs::absolute(scene_file).parent_path().filename();
  request.set_name(!args.name.empty() ? args.name
                                      : (folder / scene_file.filename()).generic_string());
  wire::JobOverrides* o = request.mutable_overrides();
  if (args.spp) o->set_spp(*args.spp);
  if (args.max_depth) o->set_max_depth(*args.max_depth);
  if (args.seed) o->set_seed(*args.seed);
  if (args.integrator)
    o->set_integrator(protocol::integrator_to_wire(*parse_integrator(*args.integrator)));
  if (args.tile) o->set_tile_size(*args.tile);
  if (args.pass_spp) o->set_pass_spp(*args.pass_spp);
  o->set_target_error(args.stop.target_error);
  o->set_time_limit_s(args.stop.time_limit);
  o->set_no_adaptive(args.stop.no_adaptive);
  o->set_min_passes(args.stop.min_passes);
  if (const auto& reference = args.stop.reference) {
    std::ifstream in(*reference, std::ios::binary);
    std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    if (!in.good() && !in.eof()) throw std::runtime_error(*reference + ": cannot read the reference");
    if (bytes.empty()) throw std::runtime_error(*reference + ": the reference is missing or empty");
    request.set_reference_exr(std::move(bytes));
  }

  FarmClient client(args.client);
  // A master checking many submissions at once says it is busy: try again, within --timeout.
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration<double>(args.client.timeout);
  auto pause = std::chrono::milliseconds{100};
  wire::SubmitReply reply = client.call<wire::SubmitReply>(encode(request));
  while (reply.error().rfind("the master is busy", 0) == 0 &&
         std::chrono::steady_clock::now() + pause < deadline) {
    std::this_thread::sleep_for(pause);
    pause = std::min(pause * 2, std::chrono::milliseconds{2000});
    reply = client.call<wire::SubmitReply>(encode(request));
  }
  if (!reply.error().empty()) throw MasterError("the master rejected the job: " + reply.error());
  std::cout << reply.job_id() << "\n" << std::flush;
  if (!args.wait) return 0;
  return watch_job(client, reply.job_id());
}

void add_submit(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<SubmitArgs>();
  CLI::App* cmd = app.add_subcommand("submit", "Submit a scene to a farm; prints the job id");
  cmd->add_option("scene", args->scene,
                  "Scene file (JSON); it and every file it uses travel with the job")
      ->required();
  add_client_options(cmd, args->client);
  cmd->add_option("--spp", args->spp, "Samples per pixel (default: the scene's)");
  cmd->add_option("--integrator", args->integrator, "naive, nee or mis (default: the scene's)")
      ->check(CLI::IsMember({"naive", "nee", "mis"}));
  cmd->add_option("--max-depth", args->max_depth, "Most scattering vertices per path");
  cmd->add_option("--seed", args->seed, "Random seed (default: the scene's)");
  cmd->add_option("--tile", args->tile,
                  "Tile size in pixels (default 64); does not change the image")
      ->check(CLI::Range(1u, 4096u));
  cmd->add_option("--pass-spp", args->pass_spp,
                  "Samples per pass (default: automatic); does not change the image")
      ->check(CLI::PositiveNumber);
  add_stop_options(cmd, args->stop,
                   "Reference EXR sent with the job: the error against it is measured at every pass");
  cmd->add_option("--name", args->name, "Job name (default: the scene file's name)");
  cmd->add_flag("--wait", args->wait,
                "Show progress until the job ends; exit 0 only when it is done");
  cmd->callback(
      [args, &exit_code] { exit_code = guarded("submit", [&] { return run_submit(*args); }); });
}

void add_status(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand("status", "Show one job in detail, or every job");
  cmd->add_option("job", *job, "Job id (default: every job)");
  add_client_options(cmd, *args);
  cmd->callback([args, job, &exit_code] {
    exit_code = guarded("status", [&] {
      FarmClient client(*args);
      if (job->empty()) {
        print_table(client.call<wire::JobList>(encode(wire::ListJobs{})));
      } else {
        print_status(query_status(client, *job));
      }
      return 0;
    });
  });
}

void add_list(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  CLI::App* cmd = app.add_subcommand("list", "List the farm's jobs");
  add_client_options(cmd, *args);
  cmd->callback([args, &exit_code] {
    exit_code = guarded("list", [&] {
      FarmClient client(*args);
      print_table(client.call<wire::JobList>(encode(wire::ListJobs{})));
      return 0;
    });
  });
}

void add_watch(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "watch", "Follow a job's progress until it ends (Ctrl-C to stop watching)");
  cmd->add_option("job", *job, "Job id")->required();
  add_client_options(cmd, *args);
  cmd->callback([args, job, &exit_code] {
    exit_code = guarded("watch", [&] {
      FarmClient client(*args);
      return watch_job(client, *job);
    });
  });
}

void add_cancel(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  CLI::App* cmd =
      app.add_subcommand("cancel", "Cancel a job; its image keeps the samples merged so far");
  cmd->add_option("job", *job, "Job id")->required();
  add_client_options(cmd, *args);
  cmd->callback([args, job, &exit_code] {
    exit_code = guarded("cancel", [&] {
      FarmClient client(*args);
      wire::CancelJob request;
      request.set_job_id(*job);
      const auto reply = client.call<wire::CancelReply>(encode(std::move(request)));
      std::cout << fmt::format("job {} {}\n", reply.job_id(),
                               protocol::job_state_name(reply.state()));
      return 0;
    });
  });
}

void add_fetch(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  auto output = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "fetch", "Download a job's current or final EXR (and a PNG preview beside it)");
  cmd->add_option("job", *job, "Job id")->required();
  cmd->add_option("-o,--output", *output, "Output EXR file")->required();
  add_client_options(cmd, *args);
  cmd->callback([args, job, output, &exit_code] {
    exit_code = guarded("fetch", [&] {
      FarmClient client(*args);
      wire::FetchImage request;
      request.set_job_id(*job);
      const auto image = client.call<wire::ImageData>(encode(std::move(request)));
      write_file_atomically(*output, image.exr());
      std::string wrote = *output;
      if (!image.png().empty()) {
        const fs::path png = preview_path(*output);
        write_file_atomically(png, image.png());
        wrote += " and " + png.string();
      }
      std::cout << fmt::format("wrote {} (job {} {}, {} spp)\n", wrote, image.job_id(),
                               protocol::job_state_name(image.state()), image.spp_done());
      return 0;
    });
  });
}

}  // namespace

JobFetcher add_job_fetch_options(CLI::App* cmd) {
  auto args = std::make_shared<ClientArgs>();
  add_client_options(cmd, *args);
  return [args](const std::string& job) {
    FarmClient client(*args);
    JobSnapshot snapshot{query_status(client, job), std::nullopt, {}};
    wire::FetchImage request;
    request.set_job_id(job);
    try {
      snapshot.image = client.call<wire::ImageData>(encode(std::move(request)));
    } catch (const MasterError& e) {
      snapshot.no_image_reason = e.what();  // e.g. no unit merged yet
    }
    return snapshot;
  };
}

int run_farm_command(const char* command, const std::function<int()>& body) {
  return guarded(command, body);
}

void add_farm_commands(CLI::App& app, int& exit_code) {
  add_submit(app, exit_code);
  add_status(app, exit_code);
  add_list(app, exit_code);
  add_watch(app, exit_code);
  add_cancel(app, exit_code);
  add_fetch(app, exit_code);
}

}  // namespace rayfarm::cli
