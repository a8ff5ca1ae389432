// The farm's client commands: submit, status, list, watch, cancel, fetch. Each talks to the
// master's client endpoint over one DEALER socket: Hello, then one request and its reply, every
// wait bounded by --timeout so that an unreachable master is an error (exit 3), never a hang.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/farm_client.h"
#include "cli/film_option.h"
#include "cli/output_path.h"
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
constexpr int kExitJobUnsuccessful = 5;  // the job failed or was cancelled
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
  /// Connects and says hello, waiting at most `timeout` (default: --timeout) for each answer.
  explicit FarmClient(const ClientArgs& args,
                      std::optional<std::chrono::milliseconds> timeout = std::nullopt)
      : endpoint_(args.master),
        timeout_(timeout.value_or(std::chrono::duration_cast<std::chrono::milliseconds>(
            std::chrono::duration<double>(args.timeout)))),
        socket_(args.master, net::kDefaultMaxMessageBytes, client_curve(args)) {
    wire::Hello hello;
    hello.set_role(wire::ROLE_CLIENT);
    hello.set_name("rayfarm-cli");
    hello.set_build(protocol::kBuildVersion);
    call<wire::Welcome>(encode(std::move(hello)));
  }

  /// Sends a request and waits for a reply of type Reply. Throws Unreachable after the timeout,
  /// NotAdmitted when the master refused this client, and MasterError on an Error or Refusal.
  template <class Reply>
  Reply call(const net::Frames& request) {
    const auto deadline = std::chrono::steady_clock::now() + timeout_;
    // A send fails while no connection can take the message (e.g. one refused in its handshake):
    // try again until the deadline, saying why as soon as the handshake tells.
    while (!socket_.send(request)) {
      check_admitted();
      if (std::chrono::steady_clock::now() >= deadline) throw_unanswered();
      if (g_interrupted.load()) throw MasterError("interrupted");
      std::this_thread::sleep_for(std::chrono::milliseconds{20});
    }
    while (true) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) throw_unanswered();
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
  std::optional<net::HandshakeStatus> hung_up_;  // the master closed a handshake (see below)

  /// Throws NotAdmitted when the master refused this client's key or security. A master that
  /// only closed the connection during the handshake may be starting or stopping (or be a proxy
  /// with nothing behind it yet) as much as refusing a wrong --master-key: that is remembered and
  /// tried again until the deadline, and only then blamed on the key.
  void check_admitted() {
    const net::HandshakeStatus hs = socket_.handshake();
    if (hs.state == net::Handshake::kSucceeded) hung_up_.reset();
    if (hs.state != net::Handshake::kRefused && hs.state != net::Handshake::kFailed) return;
    if (hs.peer_closed) {
      hung_up_ = hs;
      return;
    }
    throw NotAdmitted(
        fmt::format("the master at {} did not let this client in: {}", endpoint_, hs.detail));
  }

  /// The deadline passed without an answer: NotAdmitted when every handshake was closed by the
  /// master, Unreachable otherwise.
  [[noreturn]] void throw_unanswered() {
    if (hung_up_) {
      throw NotAdmitted(fmt::format(
          "the master at {} did not let this client in: {} (it closed every handshake for {:g} s, "
          "so it is not just starting; if it is, try a longer --timeout)",
          endpoint_, hung_up_->detail, timeout_.count() / 1000.0));
    }
    throw Unreachable(unreachable_message());
  }

  /// Why nothing came back: the handshake's state says whether a connection was made at all.
  std::string unreachable_message() {
    const net::HandshakeStatus hs = socket_.handshake();
    std::string why;
    if (hs.state == net::Handshake::kDropped) {
      why = "the master did not answer: " + hs.detail +
            "; or it was starting or stopping (try again, or a longer --timeout)";
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

const char* integrator_label(wire::Integrator value) {
  try {
    return integrator_name(protocol::integrator_from_wire(value));
  } catch (const protocol::ProtocolError&) {
    return "unknown integrator";
  }
}

bool finished(wire::JobState state) {
  // JOB_STATE_UNSPECIFIED: a job whose record the master cannot read; it will not change.
  return state == wire::JOB_DONE || state == wire::JOB_FAILED || state == wire::JOB_CANCELLED ||
         state == wire::JOB_STATE_UNSPECIFIED;
}

/// A figure for JSON: null when unknown (negative or not finite).
nlohmann::json figure(double value) {
  return std::isfinite(value) && value >= 0 ? nlohmann::json(value) : nlohmann::json(nullptr);
}

/// A job's status as one JSON object (docs/cli.md lists the keys).
nlohmann::json status_json(const wire::JobStatus& st) {
  return nlohmann::json{
      {"job", st.job_id()},
      {"name", st.name()},
      {"owner", st.owner()},
      {"state", protocol::job_state_name(st.state())},
      {"storage_error",
       st.storage_error().empty() ? nlohmann::json(nullptr) : nlohmann::json(st.storage_error())},
      {"error", st.error().empty() ? nlohmann::json(nullptr) : nlohmann::json(st.error())},
      {"stop_reason",
       st.stop_reason().empty() ? nlohmann::json(nullptr) : nlohmann::json(st.stop_reason())},
      {"width", st.width()},
      {"height", st.height()},
      {"spp", st.settings().spp()},
      {"integrator", st.state() == wire::JOB_STATE_UNSPECIFIED
                         ? nlohmann::json(nullptr)
                         : nlohmann::json(integrator_label(st.settings().integrator()))},
      {"max_depth", st.settings().max_depth()},
      {"seed", st.settings().seed()},
      {"clamp", st.settings().clamp()},
      {"tile_size", st.tile_size()},
      {"pass_spp", st.pass_spp()},
      {"passes_done", st.passes_done()},
      {"passes_total", st.passes_total()},
      {"units_done", st.units_done()},
      {"units_total", st.units_total()},
      {"units_leased", st.units_leased()},
      {"percent", percent(st)},
      {"spp_done", st.spp_done()},
      {"spp_mean", st.spp_mean()},
      {"est_rel_mse", figure(st.est_rel_mse())},
      {"ref_rel_mse", figure(st.ref_rel_mse())},
      {"tiles_converged", st.tiles_converged()},
      {"tiles_total", st.tiles_total()},
      {"samples_per_second", st.samples_per_second()},
      {"elapsed_seconds", st.elapsed_seconds()},
      {"eta_seconds", figure(st.eta_seconds())},
      {"workers_busy", st.workers_busy()},
      {"workers_total", st.workers_total()}};
}

void print_json(const nlohmann::json& j) { std::cout << j.dump() << "\n" << std::flush; }

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
  if (!st.storage_error().empty()) line += "  storage: " + st.storage_error();
  return line;
}

void print_status(const wire::JobStatus& st) {
  std::cout << fmt::format("job        {} ({})\n", st.job_id(), st.name());
  std::cout << fmt::format("state      {}\n", protocol::job_state_name(st.state()));
  if (!st.owner().empty()) std::cout << fmt::format("owner      key '{}'\n", st.owner());
  if (!st.storage_error().empty()) {
    // The master cannot write the job's image, checkpoint or record (a full disk): it says why.
    std::cout << fmt::format("storage    {}\n", st.storage_error());
  }
  if (!st.error().empty()) {
    // Why it failed; for a cancelled job, who cancelled it.
    std::cout << fmt::format("{:<10} {}\n",
                             st.state() == wire::JOB_CANCELLED ? "cancelled" : "error", st.error());
  }
  if (st.state() == wire::JOB_STATE_UNSPECIFIED) return;  // nothing else is known
  std::cout << fmt::format(
      "image      {}x{}, {} spp, {}, max depth {}, seed {}{}\n", st.width(), st.height(),
      st.settings().spp(), integrator_label(st.settings().integrator()), st.settings().max_depth(),
      st.settings().seed(),
      st.settings().clamp() > 0 ? fmt::format(", clamp {:g} (biased)", st.settings().clamp()) : "");
  std::cout << fmt::format(
      "work       tiles of {} px, passes of {} spp: {}/{} units ({:.1f}%), {} leased\n",
      st.tile_size(), st.pass_spp(), st.units_done(), st.units_total(), percent(st),
      st.units_leased());
  std::cout << fmt::format("progress   pass {}/{}, {}/{} spp, {:.1f} spp mean\n", st.passes_done(),
                           st.passes_total(), st.spp_done(), st.settings().spp(), st.spp_mean());
  if (st.est_rel_mse() >= 0 || st.ref_rel_mse() >= 0) {
    std::cout << fmt::format(
        "relMSE     estimated {}{}\n",
        st.est_rel_mse() >= 0 ? fmt::format("{:.4g}", st.est_rel_mse()) : "unknown",
        st.ref_rel_mse() >= 0
            ? fmt::format(", measured against the reference {:.4g}", st.ref_rel_mse())
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
  std::cout << fmt::format("{:<8} {:<24} {:<12} {:<9} {:>7} {:>11} {:>11} {:>10}\n", "JOB", "NAME",
                           "OWNER", "STATE", "DONE", "SPP", "SIZE", "ELAPSED");
  for (const auto& st : list.jobs()) {
    std::cout << fmt::format(
        "{:<8} {:<24} {:<12} {:<9} {:>6.1f}% {:>11} {:>11} {:>10}\n", st.job_id(),
        st.name().substr(0, 24), st.owner().empty() ? "-" : st.owner().substr(0, 12),
        protocol::job_state_name(st.state()), percent(st),
        fmt::format("{}/{}", st.spp_done(), st.settings().spp()),
        fmt::format("{}x{}", st.width(), st.height()), format_duration(st.elapsed_seconds()));
  }
  for (const auto& st : list.jobs()) {
    if (st.state() == wire::JOB_STATE_UNSPECIFIED) {
      std::cout << fmt::format("{}: {}\n", st.job_id(), st.error());
    }
  }
}

/// Fetches the job's image into `output` (checked by check_output_path); returns what it wrote.
std::string fetch_image(FarmClient& client, const std::string& job, const fs::path& output,
                        OutputFormat format) {
  wire::FetchImage request;
  request.set_job_id(job);
  const auto image = client.call<wire::ImageData>(encode(std::move(request)));
  std::string wrote = output.string();
  if (format == OutputFormat::kPng) {
    if (image.png().empty()) throw MasterError("the master has no PNG preview of job " + job);
    write_file_atomically(output, image.png());
  } else {
    write_file_atomically(output, image.exr());
    if (!image.png().empty()) {
      const fs::path png = preview_path(output);
      write_file_atomically(png, image.png());
      wrote += " and " + png.string();
    }
  }
  return fmt::format("wrote {} (job {} {}, {} spp)", wrote, image.job_id(),
                     protocol::job_state_name(image.state()), image.spp_done());
}

wire::JobStatus query_status(FarmClient& client, const std::string& job) {
  wire::StatusRequest request;
  request.set_job_id(job);
  return client.call<wire::JobStatus>(encode(std::move(request)));
}

/// Asks for a job's status again and again, riding out a master that restarts: a request that
/// gets no answer (or a connection the master closed) is tried again on a new connection until
/// --timeout has passed since the master last answered.
class StatusPoller {
 public:
  StatusPoller(const ClientArgs& args, const char* command)
      : args_(args),
        command_(command),
        budget_(std::chrono::duration_cast<std::chrono::milliseconds>(
            std::chrono::duration<double>(args.timeout))),
        last_answer_(std::chrono::steady_clock::now()) {}

  wire::JobStatus status(const std::string& job) {
    return with_retry([&](FarmClient& client) { return query_status(client, job); });
  }

  /// Runs `request` on the connection, retrying as status() does.
  template <class F>
  auto with_retry(F&& request) -> decltype(request(std::declval<FarmClient&>())) {
    while (true) {
      const auto now = std::chrono::steady_clock::now();
      const auto left =
          budget_ - std::chrono::duration_cast<std::chrono::milliseconds>(now - last_answer_);
      try {
        // Each try waits a short while: a master that went away will not answer on the old
        // connection, and a new one reaches the master that came back.
        if (!client_) {
          client_ = std::make_unique<FarmClient>(
              args_, std::clamp(left, std::chrono::milliseconds{100}, kTry));
        }
        auto result = request(*client_);
        if (retrying_) std::cerr << "rayfarm " << command_ << ": the master answers again\n";
        retrying_ = false;
        answered_ = true;
        last_answer_ = std::chrono::steady_clock::now();
        return result;
      } catch (const Unreachable&) {
        if (!keep_trying()) throw;
      } catch (const NotAdmitted&) {
        // Refused before it ever answered: the key, told at once. After: a master restarting.
        if (!answered_ || !keep_trying()) throw;
      }
    }
  }

 private:
  static constexpr std::chrono::milliseconds kTry{3000};
  ClientArgs args_;
  const char* command_;
  std::chrono::milliseconds budget_;
  std::chrono::steady_clock::time_point last_answer_;
  std::unique_ptr<FarmClient> client_;
  bool retrying_ = false;
  bool answered_ = false;

  /// After a failed try: false when --timeout has passed since the last answer.
  bool keep_trying() {
    client_.reset();
    if (g_interrupted.load()) throw MasterError("interrupted");
    const auto silent = std::chrono::steady_clock::now() - last_answer_;
    if (silent >= budget_) return false;
    if (!retrying_) {
      std::cerr << fmt::format(
          "rayfarm {}: the master at {} does not answer; trying again for up to {:g} s "
          "(--timeout)\n",
          command_, args_.master, budget_.count() / 1000.0);
      retrying_ = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds{200});
    return true;
  }
};

/// Shows the job's progress until it ends (a live line on a terminal, plain lines otherwise, or
/// with `json` one status object per line whenever it changes); returns the exit code for its
/// final state.
int watch_job(StatusPoller& poller, const std::string& job, bool json) {
  const bool tty = !json && isatty(STDOUT_FILENO) != 0;
  std::signal(SIGINT, on_sigint);
  std::string last_line;
  auto last_print = std::chrono::steady_clock::now() - std::chrono::hours(1);
  while (true) {
    const wire::JobStatus st = poller.status(job);
    const auto now = std::chrono::steady_clock::now();
    if (json) {
      // A line when the job moved (units, passes, state), not for the clock alone.
      const std::string key = fmt::format("{}/{}/{}/{}", static_cast<int>(st.state()),
                                          st.units_done(), st.passes_done(), st.units_leased());
      if (key != last_line) print_json(status_json(st));
      last_line = key;
    } else {
      const std::string line = progress_line(st);
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
  bool json = false;
  float clamp = 0.f;
  std::string output;
  StopArgs stop;
  FilmArgs film;
};

int run_submit(const SubmitArgs& args) {
  std::optional<OutputFormat> format;
  if (!args.output.empty()) {
    if (!args.wait)
      throw std::invalid_argument("-o needs --wait: the image is fetched when the job is done");
    format = check_output_path(args.output);  // before the job is sent
  }
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
  o->set_clamp(args.clamp);
  if (args.film.given()) {
    const auto film = args.film.resolve(load_scene(args.scene).film);
    o->set_width(film->width);
    o->set_height(film->height);
  }
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
  if (code != 0 || !format) return code;
  const std::string wrote = poller.with_retry(
      [&](FarmClient& client) { return fetch_image(client, job, args.output, *format); });
  std::cerr << wrote << "\n";
  return 0;
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
  add_film_options(cmd, args->film);
  add_clamp_option(cmd, args->clamp);
  add_stop_options(cmd, args->stop,
                   "Reference EXR sent with the job: the error against it is measured at every pass");
  cmd->add_option("--name", args->name, "Job name (default: the scene file's name)");
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

void add_status(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("status", "Show one job in detail, or every job");
  cmd->add_option("job", *job, "Job id (default: every job)");
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "One JSON object (per job, one a line)");
  cmd->callback([args, job, json, &exit_code] {
    exit_code = guarded("status", [&] {
      FarmClient client(*args);
      if (job->empty()) {
        const auto list = client.call<wire::JobList>(encode(wire::ListJobs{}));
        if (*json) {
          for (const auto& st : list.jobs()) print_json(status_json(st));
        } else {
          print_table(list);
        }
      } else if (*json) {
        print_json(status_json(query_status(client, *job)));
      } else {
        print_status(query_status(client, *job));
      }
      return 0;
    });
  });
}

void add_list(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("list", "List the farm's jobs");
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "One JSON object per job, one a line");
  cmd->callback([args, json, &exit_code] {
    exit_code = guarded("list", [&] {
      FarmClient client(*args);
      const auto list = client.call<wire::JobList>(encode(wire::ListJobs{}));
      if (*json) {
        for (const auto& st : list.jobs()) print_json(status_json(st));
      } else {
        print_table(list);
      }
      return 0;
    });
  });
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

void add_remove(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "rm", "Remove a finished (done, failed or cancelled) job and its files from the master");
  cmd->add_option("job", *job, "Job id")->required();
  add_client_options(cmd, *args);
  cmd->callback([args, job, &exit_code] {
    exit_code = guarded("rm", [&] {
      FarmClient client(*args);
      wire::RemoveJob request;
      request.set_job_id(*job);
      const auto reply = client.call<wire::RemoveReply>(encode(std::move(request)));
      std::cout << fmt::format("job {} removed\n", reply.job_id());
      return 0;
    });
  });
}

void add_retry(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "retry", "Run a failed or cancelled job again from its first sample, under the same id");
  cmd->add_option("job", *job, "Job id")->required();
  add_client_options(cmd, *args);
  cmd->callback([args, job, &exit_code] {
    exit_code = guarded("retry", [&] {
      FarmClient client(*args);
      wire::RetryJob request;
      request.set_job_id(*job);
      const auto reply = client.call<wire::RetryReply>(encode(std::move(request)));
      std::cout << fmt::format("job {} {}\n", reply.job_id(),
                               protocol::job_state_name(reply.state()));
      return 0;
    });
  });
}

nlohmann::json worker_json(const wire::WorkerInfo& w) {
  return nlohmann::json{
      {"id", w.id()},
      {"name", w.name()},
      {"key_name", w.key_name().empty() ? nlohmann::json(nullptr) : nlohmann::json(w.key_name())},
      {"state", w.units().empty() ? "idle" : "busy"},
      {"threads", w.threads()},
      {"units", w.units()},
      {"units_done", w.units_done()},
      {"samples_per_second", w.samples_per_second()},
      {"last_seen_seconds", w.last_seen_seconds()},
      {"build", w.build()}};
}

void add_workers(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("workers", "List the workers connected to the master");
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "One JSON object per worker, one a line");
  cmd->callback([args, json, &exit_code] {
    exit_code = guarded("workers", [&] {
      FarmClient client(*args);
      const auto list = client.call<wire::WorkerList>(encode(wire::ListWorkers{}));
      if (*json) {
        for (const auto& w : list.workers()) print_json(worker_json(w));
        return 0;
      }
      if (list.workers().empty()) {
        std::cout << "no workers connected\n";
        return 0;
      }
      std::cout << fmt::format("{:<20} {:<16} {:<5} {:>7} {:<16} {:>6} {:>16} {:>9}\n", "NAME",
                               "KEY", "STATE", "THREADS", "UNIT", "DONE", "RATE", "SEEN");
      for (const auto& w : list.workers()) {
        std::string units = w.units().empty() ? "-" : w.units(0);
        if (w.units_size() > 1) units += fmt::format(" +{}", w.units_size() - 1);
        std::cout << fmt::format(
            "{:<20} {:<16} {:<5} {:>7} {:<16} {:>6} {:>16} {:>9}\n", w.name().substr(0, 20),
            w.key_name().empty() ? "-" : w.key_name().substr(0, 16),
            w.units().empty() ? "idle" : "busy", w.threads(), units, w.units_done(),
            format_rate(w.samples_per_second()), format_duration(w.last_seen_seconds()) + " ago");
      }
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
  cmd->add_option(
         "-o,--output", *output,
         "Output: x.exr (and its PNG preview x.png beside it) or x.png (the preview alone)")
      ->required();
  add_client_options(cmd, *args);
  cmd->callback([args, job, output, &exit_code] {
    exit_code = guarded("fetch", [&] {
      const OutputFormat format = check_output_path(*output);
      FarmClient client(*args);
      std::cout << fetch_image(client, *job, *output, format) << "\n";
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
  add_workers(app, exit_code);
  add_remove(app, exit_code);
  add_retry(app, exit_code);
}

}  // namespace rayfarm::cli
