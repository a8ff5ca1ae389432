// rayfarm-worker: connects to a master, renders the units it is given, and stops cleanly on
// SIGINT or SIGTERM after the unit in hand.
#include <atomic>
#include <csignal>
#include <exception>
#include <iostream>

#include <CLI/CLI.hpp>

#include "common/net/peer_options.h"
#include "common/protocol/version.h"
#include "common/util/log.h"
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
  int64_t stop_grace_ms = options.stop_grace.count();
  app.add_option("--stop-grace-ms", stop_grace_ms,
                 "on SIGTERM, how long to wait for the units in hand before handing them back; "
                 "keep it 2 s under the time the deployment waits before SIGKILL")
      ->check(CLI::Range(int64_t{0}, int64_t{3600000}))
      ->capture_default_str();
  rayfarm::net::PeerKeyOptions keys;
  rayfarm::net::add_peer_key_options(app, keys, "worker");
  app.set_version_flag("--version", rayfarm::protocol::kBuildVersion);
  CLI11_PARSE(app, argc, argv);

  logging.apply();
  rayfarm::get_logger("worker")->info("rayfarm-worker: {} (protocol {})", rayfarm::protocol::kBuildVersion,
                                   rayfarm::protocol::kProtocolVersion);
  options.cache_dir = cache_dir;
  options.stop_grace = std::chrono::milliseconds{stop_grace_ms};
  options.heartbeat.interval = std::chrono::milliseconds{heartbeat_ms};
  options.heartbeat.reconnect_max = std::chrono::milliseconds{reconnect_max_ms};
  options.heartbeat.reconnect_min =
      std::min(options.heartbeat.reconnect_min, options.heartbeat.reconnect_max);

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  try {
    options.curve = rayfarm::net::peer_curve(keys, "the worker");
    rayfarm::worker::Agent agent(options);
    return agent.run(g_stop);
  } catch (const std::exception& e) {
    rayfarm::get_logger("worker")->critical("{}", e.what());
    return 1;
  }
}
