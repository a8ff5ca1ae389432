#pragma once
// The farm's client: one DEALER connection to the master's client endpoint (Hello, then one
// request and its reply, every wait bounded by --timeout so that an unreachable master is an
// error, never a hang), its options, its errors and the exit codes they become. Used by the farm
// commands and by report.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "cli/output_path.h"
#include "common/net/peer_options.h"
#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::cli {

inline constexpr int kExitError = 1;
inline constexpr int kExitUnreachable = 3;
inline constexpr int kExitRefused = 4;  // the master did not admit this client (key, security)
inline constexpr int kExitJobUnsuccessful = 5;  // the job failed or was cancelled
inline constexpr int kExitInterrupted = 130;

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

/// Whether Ctrl-C was pressed since catch_interrupts().
bool interrupted();
/// From now on, Ctrl-C sets interrupted() instead of ending the process.
void catch_interrupts();

/// --master, --timeout and the keys.
struct ClientArgs {
  std::string master = default_master();
  double timeout = 10.0;
  net::PeerKeyOptions keys;

  /// $RAYFARM_MASTER, or tcp://localhost:5556.
  static std::string default_master();
};

/// Adds --master, --timeout, --key and --master-key (or --insecure) to `cmd`.
void add_client_options(CLI::App* cmd, ClientArgs& args);

/// One connection to the master's client endpoint.
class FarmClient {
 public:
  /// Connects and says hello, waiting at most `timeout` (default: --timeout) for each answer.
  explicit FarmClient(const ClientArgs& args,
                      std::optional<std::chrono::milliseconds> timeout = std::nullopt);

  /// Sends a request and waits for a reply of type Reply. Throws Unreachable after the timeout,
  /// NotAdmitted when the master refused this client, and MasterError on an Error or Refusal.
  /// A request refused as busy (Error BUSY: a key past its budget of changes, docs/reliability.md)
  /// changed nothing: it is sent again, backing off, until the timeout.
  template <class Reply>
  Reply call(const net::Frames& request) {
    const auto deadline = std::chrono::steady_clock::now() + timeout_;
    auto backoff = std::chrono::milliseconds{100};
    const auto send = [&] {
      // A send fails while no connection can take the message (e.g. one refused in its
      // handshake): try again until the deadline, saying why as soon as the handshake tells.
      while (!socket_.send(request)) {
        check_admitted();
        if (std::chrono::steady_clock::now() >= deadline) throw_unanswered();
        if (interrupted()) throw MasterError("interrupted");
        std::this_thread::sleep_for(std::chrono::milliseconds{20});
      }
    };
    send();
    while (true) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) throw_unanswered();
      auto frames = socket_.receive(std::min(left, std::chrono::milliseconds{100}));
      if (!frames) {
        if (interrupted()) throw MasterError("interrupted");
        check_admitted();
        continue;
      }
      protocol::Decoded msg = protocol::decode(*frames);
      if (const auto* refusal = msg.as<wire::Refusal>()) throw MasterError(refusal->reason());
      if (const auto* error = msg.as<wire::Error>()) {
        if (error->code() == wire::Error::BUSY &&
            std::chrono::steady_clock::now() + backoff < deadline && !interrupted()) {
          std::this_thread::sleep_for(backoff);
          backoff = std::min(backoff * 2, std::chrono::milliseconds{2000});
          send();
          continue;
        }
        throw MasterError(error->message());
      }
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
  void check_admitted();
  /// The deadline passed without an answer: NotAdmitted when every handshake was closed by the
  /// master, Unreachable otherwise.
  [[noreturn]] void throw_unanswered();
  /// Why nothing came back: the handshake's state says whether a connection was made at all.
  std::string unreachable_message();
};

/// Runs `body`, turning the farm's failures into messages and exit codes.
template <class Body>
int guarded(const char* command, Body&& body) {
  try {
    return body();
  } catch (const CLI::ParseError&) {
    throw;  // a usage error found after parsing (main.cpp: exit 2, with the usage line)
  } catch (const Unreachable& e) {
    std::cerr << "rayfarm " << command << ": error: " << e.what() << "\n";
    return kExitUnreachable;
  } catch (const NotAdmitted& e) {
    std::cerr << "rayfarm " << command << ": error: " << e.what() << "\n";
    return kExitRefused;
  } catch (const std::exception& e) {
    if (interrupted()) return kExitInterrupted;
    std::cerr << "rayfarm " << command << ": error: " << e.what() << "\n";
    return kExitError;
  }
}

/// The job's status now.
wire::JobStatus query_status(FarmClient& client, const std::string& job);
/// Fetches frames of sequence `job` to `pattern` (frame_output_path: '#' or %04d take the frame
/// number): frame `only` (to `pattern` itself when it holds no '#' or '%'), or every frame that
/// is done when nullopt. Returns a line per image
/// written. Throws MasterError when the job is not a sequence, has no such frame, or has no frame
/// done.

/// Fetches the job's image into `output` (checked by check_output_path); returns what it wrote.
std::vector<std::string> fetch_frames(FarmClient& client, const std::string& job,
                                      const std::filesystem::path& pattern, OutputFormat format,
                                      std::optional<int64_t> only);
std::string fetch_image(FarmClient& client, const std::string& job,
                        const std::filesystem::path& output, OutputFormat format);

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
    if (interrupted()) throw MasterError("interrupted");
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

/// A job as the master has it now: its status and, once a unit has been merged, its image (with
/// error.csv and error.png when the master wrote them).
struct JobSnapshot {
  wire::JobStatus status;
  std::optional<wire::ImageData> image;
  std::string no_image_reason;  ///< the master's answer when there is no image
};

/// Fetches a job's snapshot; throws as the farm commands' client does (see run_farm_command).
using JobFetcher = std::function<JobSnapshot(const std::string& job_id)>;

/// Adds --master (default $RAYFARM_MASTER or tcp://localhost:5556) and --timeout to `cmd`;
/// the returned fetcher uses their values, so call it only after parsing.
JobFetcher add_job_fetch_options(CLI::App* cmd);

/// Runs `body` as the farm commands run theirs: an error is printed as "rayfarm COMMAND: error:
/// cause"; returns body's exit code, 1 on an error, 3 when the master is unreachable.
int run_farm_command(const char* command, const std::function<int()>& body);

}  // namespace rayfarm::cli
