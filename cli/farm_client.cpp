#include "cli/farm_client.h"

#include <csignal>
#include <cstdlib>

#include "common/image/film_output.h"
#include "common/protocol/convert.h"
#include "common/protocol/version.h"
#include "common/util/atomic_file.h"

namespace rayfarm::cli {
namespace fs = std::filesystem;
using protocol::encode;

namespace {

std::atomic<bool> g_interrupted{false};
void on_sigint(int) { g_interrupted.store(true); }

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

}  // namespace

bool interrupted() { return g_interrupted.load(); }
void catch_interrupts() { std::signal(SIGINT, on_sigint); }

std::string ClientArgs::default_master() {
  const char* env = std::getenv("RAYFARM_MASTER");
  return env && *env ? env : "tcp://localhost:5556";
}

void add_client_options(CLI::App* cmd, ClientArgs& args) {
  cmd->add_option("--master", args.master, "the master's client endpoint (env RAYFARM_MASTER)")
      ->capture_default_str();
  cmd->add_option("--timeout", args.timeout, "seconds to wait for the master")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  net::add_peer_key_options(*cmd, args.keys, "client");
}

FarmClient::FarmClient(const ClientArgs& args, std::optional<std::chrono::milliseconds> timeout)
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

void FarmClient::check_admitted() {
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

void FarmClient::throw_unanswered() {
  if (hung_up_) {
    throw NotAdmitted(fmt::format(
        "the master at {} did not let this client in: {} (it closed every handshake for {:g} s, "
        "so it is not just starting; if it is, try a longer --timeout)",
        endpoint_, hung_up_->detail, timeout_.count() / 1000.0));
  }
  throw Unreachable(unreachable_message());
}

std::string FarmClient::unreachable_message() {
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

std::string fetch_image(FarmClient& client, const std::string& job, const fs::path& output,
                        OutputFormat format) {
  wire::FetchImage request;
  request.set_job_id(job);
  request.set_movie(format == OutputFormat::kMp4);
  request.set_contact_sheet(format == OutputFormat::kPng);  // what a sequence has as a PNG
  const auto image = client.call<wire::ImageData>(encode(std::move(request)));
  std::string wrote = output.string();
  // A sequence has no image of its own: its contact sheet (a PNG) and its movie.
  const bool sequence = image.exr().empty() && (!image.png().empty() || !image.mp4().empty());
  if (format == OutputFormat::kMp4) {
    if (image.mp4().empty()) throw MasterError("the master sent no movie of job " + job);
    write_file_atomically(output, image.mp4());
    return fmt::format("wrote {} (the movie of sequence {}, {})", wrote, image.job_id(),
                       protocol::job_state_name(image.state()));
  }
  if (sequence) {  // asked for as a PNG: the master sends a sequence's sheet only then
    write_file_atomically(output, image.png());
    return fmt::format("wrote {} (the contact sheet of sequence {}, {})", wrote, image.job_id(),
                       protocol::job_state_name(image.state()));
  }
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
  // The image's samples per pixel; the job's beside them when the image lags it (a master
  // before job_spp_done sent the job's figure alone).
  std::string lag;
  if (image.job_spp_done() != 0 && image.job_spp_done() != image.spp_done()) {
    lag = fmt::format("; the job is at {} spp", image.job_spp_done());
  }
  if (!image.image_note().empty()) {
    lag += (lag.empty() ? "; " : ": ") + protocol::printable(image.image_note());
  }
  return fmt::format("wrote {} (job {} {}, {} spp{})", wrote, image.job_id(),
                     protocol::job_state_name(image.state()), image.spp_done(), lag);
}

std::vector<std::string> fetch_frames(FarmClient& client, const std::string& job,
                                      const fs::path& pattern, OutputFormat format,
                                      std::optional<int64_t> only) {
  const wire::JobStatus st = query_status(client, job);
  if (st.frames_size() == 0) {
    throw MasterError("job " + job + " is not a sequence: fetch it without --frame or --all");
  }
  std::vector<std::string> out;
  for (const wire::SequenceFrame& f : st.frames()) {
    if (only ? f.frame() != *only : f.state() != wire::JOB_DONE) continue;
    // One frame asked for by name goes to the name as given when it holds no pattern.
    const fs::path output =
        only && !has_frame_pattern(pattern) ? pattern : frame_output_path(pattern, f.frame());
    out.push_back(fetch_image(client, f.job_id(), output, format));
  }
  if (out.empty()) {
    throw MasterError(only ? fmt::format("sequence {} has no frame {}", job, *only)
                           : fmt::format("sequence {} has no frame done yet", job));
  }
  return out;
}

wire::JobStatus query_status(FarmClient& client, const std::string& job) {
  wire::StatusRequest request;
  request.set_job_id(job);
  return client.call<wire::JobStatus>(encode(std::move(request)));
}

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

}  // namespace rayfarm::cli
