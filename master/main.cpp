// rayfarm-master: binds the worker and client endpoints and serves jobs until SIGINT or SIGTERM.
#include <algorithm>
#include <atomic>
#include <csignal>
#include <exception>
#include <iostream>
#include <thread>

#include <CLI/CLI.hpp>

#include "common/limits.h"
#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/protocol/version.h"
#include "common/util/log.h"
#include "common/util/log_options.h"
#include "master/broker.h"
#include "master/memory_return.h"

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }

}  // namespace

int main(int argc, char** argv) {
  rayfarm::master::tune_allocator();  // before any thread: docs/reliability.md, "Memory"
  CLI::App app{"rayfarm-master: hands out units of work to workers and merges their results"};
  rayfarm::master::MasterOptions options;
  std::string data_dir = options.data_dir.string();
  rayfarm::LoggingOptions logging;
  int64_t heartbeat_ms = options.heartbeat.interval.count();
  int64_t image_interval_ms = options.image_interval.count();
  app.add_option("--worker-endpoint", options.worker_endpoint, "endpoint workers connect to")
      ->capture_default_str();
  app.add_option("--client-endpoint", options.client_endpoint,
                 "endpoint clients (rayfarm) connect to")
      ->capture_default_str();
  app.add_option("--data-dir", data_dir, "jobs, bundles and images")->capture_default_str();
  options.http_endpoint = "127.0.0.1:8480";
  CLI::Option* http_option =
      app.add_option("--http-endpoint", options.http_endpoint,
                     "HOST:PORT of the dashboard, its JSON API and /metrics (\"\" = none); beyond "
                     "loopback only with keys, whose tokens (rayfarm token) guard its actions "
                     "[env RAYFARM_HTTP_ENDPOINT]")
          ->envname("RAYFARM_HTTP_ENDPOINT")
          ->capture_default_str();
  app.add_flag("--http-anonymous-read", options.http_anonymous_read,
               "let anyone who reaches the HTTP endpoint read jobs and workers without a token, "
               "also beyond loopback (on loopback they always may)");
  rayfarm::add_logging_options(app, logging);
  app.add_option("--heartbeat-ms", heartbeat_ms, "heartbeat interval in milliseconds")
      ->check(CLI::Range(int64_t{10}, int64_t{60000}))
      ->capture_default_str();
  app.add_option("--liveness", options.heartbeat.liveness,
                 "heartbeat intervals of silence before a worker is declared lost")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--image-interval-ms", image_interval_ms,
                 "rewrite a running job's image this often while results arrive, and at a "
                 "completed pass if none is newer (milliseconds; longer for an image whose "
                 "writing would take more than --write-share of a core)")
      ->check(CLI::Range(int64_t{100}, int64_t{3600000}))
      ->capture_default_str();
  // Durability: checkpoints, failing workers, stragglers (docs/reliability.md).
  rayfarm::master::JobManagerOptions& durability = options.jobs;
  int64_t checkpoint_interval_ms = durability.checkpoint_interval.count();
  int64_t straggler_min_ms = durability.stragglers.floor.count();
  app.add_option("--checkpoint-interval-ms", checkpoint_interval_ms,
                 "checkpoint a running job this often while results arrive, and at a completed "
                 "pass if none is newer (milliseconds; longer as --write-share asks; 0 = only at "
                 "every pass and shutdown)")
      ->check(CLI::Range(int64_t{0}, int64_t{3600000}))
      ->capture_default_str();
  app.add_option("--max-worker-failures", durability.max_worker_failures,
                 "failures (failed units, rejected results) after which a worker gets no more "
                 "units of that job")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--max-unit-failures", durability.max_unit_failures,
                 "different workers a unit may fail on before its job fails")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--straggler-factor", durability.stragglers.factor,
                 "lease a unit again to an idle worker once it has run this many times its job's "
                 "median unit (0 = never)")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  app.add_option("--straggler-min-ms", straggler_min_ms,
                 "... and at least this long (milliseconds)")
      ->check(CLI::Range(int64_t{0}, int64_t{86400000}))
      ->capture_default_str();
  app.add_option("--write-share", durability.write_share,
                 "the most share of one core that a running job's progressive images, and apart "
                 "its checkpoints, may take: their intervals stretch to keep within it (0 = the "
                 "intervals as given)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  // Units sized by time (master/scheduler.h, "Runs"; docs/farm.md).
  double unit_seconds = 2.0;
  app.add_option("--unit-seconds", unit_seconds,
                 "let one lease cover as many of a tile's passes as take about this long on the "
                 "worker that gets it, from its measured time per unit (0 = one pass per lease); "
                 "the image does not change")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  app.add_option("--max-run-units", durability.runs.max_units, "most passes one lease covers")
      ->check(CLI::Range(1u, 4096u))
      ->capture_default_str();
  app.add_option("--ffmpeg", durability.ffmpeg,
                 "the ffmpeg program that makes a finished sequence's MP4 movie (a path, or a "
                 "name looked up in PATH; \"\" = no movies); without it only the movie is "
                 "skipped")
      ->capture_default_str();

  // Security: CURVE with allow-lists by default; --insecure only on loopback.
  std::string key_file, worker_keys, client_keys;
  bool insecure = false;
  app.add_option("--key", key_file,
                 "the master's secret key file (NAME.key_secret from rayfarm "
                 "keygen) [env RAYFARM_MASTER_SECRET_KEY]")
      ->envname("RAYFARM_MASTER_SECRET_KEY");
  app.add_option("--worker-keys", worker_keys,
                 "allow-list of worker public keys: a folder of NAME.key files or a file of keys "
                 "[env RAYFARM_WORKER_KEYS]")
      ->envname("RAYFARM_WORKER_KEYS");
  app.add_option("--client-keys", client_keys,
                 "allow-list of client public keys: a folder of NAME.key files or a file of keys "
                 "[env RAYFARM_CLIENT_KEYS]")
      ->envname("RAYFARM_CLIENT_KEYS");
  std::vector<std::string> admin_clients;
  app.add_option("--admin-clients", admin_clients,
                 "names of client keys (as in --client-keys) that may cancel any job; every other "
                 "key may cancel only its own jobs [env RAYFARM_ADMIN_CLIENTS, comma-separated]")
      ->delimiter(',')
      ->envname("RAYFARM_ADMIN_CLIENTS");
  app.add_flag("--private-jobs", options.security.private_jobs,
               "a client key sees (status, list, fetch) only its own jobs, unless it is an admin");
  app.add_option("--max-client-priority", options.security.max_client_priority,
                 "highest priority a client key that is not an admin may give a job; admins, and "
                 "every client of a master without keys, may go to 100 "
                 "[env RAYFARM_MAX_CLIENT_PRIORITY]")
      ->check(CLI::Range(0, rayfarm::kMaxPriority))  // below 0 would refuse the default
      ->envname("RAYFARM_MAX_CLIENT_PRIORITY")
      ->capture_default_str();
  app.add_flag("--insecure", insecure,
               "plain sockets, no authentication or encryption: only on loopback endpoints");

  // Limits on what a peer can make the master do.
  rayfarm::master::Limits& limits = options.limits;
  int64_t max_message_mb = limits.max_message_bytes >> 20;
  uint64_t max_bundle_mb = limits.max_bundle_bytes >> 20;
  int io_threads = 0;
  app.add_option("--io-threads", io_threads,
                 "ZeroMQ I/O threads, which receive results and with CURVE decrypt them, each "
                 "worker's connection on one (0 = a quarter of the cores, 1 to 4)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  app.add_option("--max-message-mb", max_message_mb,
                 "largest message a socket accepts, in MiB; a peer sending more is disconnected")
      ->check(CLI::Range(int64_t{1}, int64_t{1024}))
      ->capture_default_str();
  app.add_option("--max-bundle-mb", max_bundle_mb, "largest scene bundle a job may bring, in MiB")
      ->check(CLI::Range(uint64_t{1}, uint64_t{4096}))
      ->capture_default_str();
  app.add_option("--max-bundle-files", limits.max_bundle_files,
                 "most files a scene bundle may hold")
      ->check(CLI::Range(uint64_t{1}, uint64_t{1} << 20))
      ->capture_default_str();
  app.add_option("--max-image-pixels", limits.max_image_pixels,
                 "most pixels (width x height) of a job's image")
      ->check(CLI::Range(uint64_t{1}, uint64_t{1} << 26))
      ->capture_default_str();
  app.add_option("--max-spp", limits.max_spp, "most samples per pixel of a job")
      ->check(CLI::Range(1u, 1u << 24))
      ->capture_default_str();
  app.add_option("--max-queued-jobs", limits.max_queued_jobs,
                 "most jobs queued or running; more submissions are refused until some finish")
      ->check(CLI::Range(size_t{1}, size_t{1000000}))
      ->capture_default_str();
  app.set_version_flag("--version", rayfarm::protocol::kBuildVersion);
  CLI11_PARSE(app, argc, argv);
  limits.max_message_bytes = max_message_mb << 20;
  limits.max_bundle_bytes = max_bundle_mb << 20;

  logging.apply();
  rayfarm::get_logger("master")->info("rayfarm-master: {} (protocol {})", rayfarm::protocol::kBuildVersion,
                                   rayfarm::protocol::kProtocolVersion);
  options.data_dir = data_dir;
  options.http_endpoint_is_default = http_option->count() == 0;
  options.heartbeat.interval = std::chrono::milliseconds{heartbeat_ms};
  options.image_interval = std::chrono::milliseconds{image_interval_ms};
  durability.checkpoint_interval = std::chrono::milliseconds{checkpoint_interval_ms};
  durability.stragglers.floor = std::chrono::milliseconds{straggler_min_ms};
  durability.runs.target = std::chrono::duration<double>(unit_seconds);

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  try {
    if (!insecure) {
      if (key_file.empty()) {
        throw std::runtime_error(
            "the master needs its key: --key FILE (a secret key file from `rayfarm keygen "
            "--name master`) with --worker-keys and --client-keys, or --insecure for a quick try "
            "on loopback endpoints");
      }
      options.security.key = rayfarm::net::key_pair_from(key_file, "--key");
      options.security.worker_keys = worker_keys;
      options.security.client_keys = client_keys;
      options.security.admin_clients.insert(admin_clients.begin(), admin_clients.end());
    }
    if (io_threads == 0) {
      io_threads = static_cast<int>(std::clamp(std::thread::hardware_concurrency() / 4, 1u, 4u));
    }
    rayfarm::net::set_io_threads(io_threads);
    rayfarm::get_logger("master")->info("{} ZeroMQ I/O thread{}", io_threads,
                                        io_threads == 1 ? "" : "s");
    rayfarm::master::Broker broker(options);
    broker.run(g_stop);
  } catch (const std::exception& e) {
    rayfarm::get_logger("master")->critical("{}", e.what());
    return 1;
  }
  return 0;
}
