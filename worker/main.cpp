// rayfarm-worker: connects to a master, renders the units it is given, and stops cleanly on
// SIGINT or SIGTERM after the unit in hand.
#include <atomic>
#include <csignal>
#include <exception>
#include <iostream>

#include <CLI/CLI.hpp>

#include "common/net/keys.h"
#include "common/util/log_options.h"
#include "worker/agent.h"

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rayfarm-worker: renders units of work for a rayfarm master"};
  rayfarm::worker::AgentOptions options;
  std::string cache_dir = options.cache_dir.string();
  rayfarm::LoggingOptions logging;
  int64_t heartbeat_ms = options.heartbeat.interval.count();
  int64_t reconnect_max_ms = options.heartbeat.reconnect_max.count();
  app.add_option("--master", options.master, "the master's worker endpoint")->capture_default_str();
  app.add_option("--threads", options.threads, "render threads (0 = all hardware threads)")
      ->capture_default_str();
  app.add_option("--cache-dir", cache_dir, "where scene bundles are cached")->capture_default_str();
  app.add_option("--name", options.name, "name in the master's logs (default host-pid)");
  app.add_option("--units-in-flight", options.units_in_flight,
                 "units rendered at once (0 = 2 with two or more threads, else 1)")
      ->capture_default_str();
  rayfarm::add_logging_options(app, logging);
  app.add_option("--heartbeat-ms", heartbeat_ms, "heartbeat interval in milliseconds")
      ->check(CLI::Range(int64_t{10}, int64_t{60000}))
      ->capture_default_str();
  app.add_option("--liveness", options.heartbeat.liveness,
                 "heartbeat intervals of silence before the master is considered gone")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--reconnect-max-ms", reconnect_max_ms, "longest back-off between reconnections")
      ->check(CLI::Range(int64_t{10}, int64_t{600000}))
      ->capture_default_str();
  std::string key, master_key;
  bool insecure = false;
  app.add_option("--key", key,
                 "this worker's secret key file (NAME.key_secret from rayfarm keygen), or the "
                 "Z85 secret key [env RAYFARM_KEY]")
      ->envname("RAYFARM_KEY");
  app.add_option("--master-key", master_key,
                 "the master's public key: its NAME.key file or the Z85 key "
                 "[env RAYFARM_MASTER_KEY]")
      ->envname("RAYFARM_MASTER_KEY");
  app.add_flag("--insecure", insecure,
               "plain socket, no authentication or encryption: only to a master on loopback");
  CLI11_PARSE(app, argc, argv);

  logging.apply();
  options.cache_dir = cache_dir;
  options.heartbeat.interval = std::chrono::milliseconds{heartbeat_ms};
  options.heartbeat.reconnect_max = std::chrono::milliseconds{reconnect_max_ms};
  options.heartbeat.reconnect_min =
      std::min(options.heartbeat.reconnect_min, options.heartbeat.reconnect_max);

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  try {
    if (!insecure) {
      if (key.empty() || master_key.empty()) {
        throw std::runtime_error(
            "the worker needs its key pair and the master's public key: --key FILE and "
            "--master-key FILE|KEY (or RAYFARM_KEY, RAYFARM_MASTER_KEY), or --insecure for a "
            "master on loopback");
      }
      rayfarm::net::require_curve();
      const rayfarm::net::KeyPair pair = rayfarm::net::key_pair_from(key, "--key");
      options.curve.public_key = pair.public_key;
      options.curve.secret_key = pair.secret_key;
      options.curve.server_key = rayfarm::net::public_key_from(master_key, "--master-key");
    }
    rayfarm::worker::Agent agent(options);
    return agent.run(g_stop);
  } catch (const std::exception& e) {
    rayfarm::get_logger("worker")->critical("{}", e.what());
    return 1;
  }
}
