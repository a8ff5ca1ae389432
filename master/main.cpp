// rayfarm-master: binds the worker and client endpoints and serves jobs until SIGINT or SIGTERM.
#include <atomic>
#include <csignal>
#include <exception>
#include <iostream>

#include <CLI/CLI.hpp>

#include "common/util/log_options.h"
#include "master/broker.h"

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }

}  // namespace

int main(int argc, char** argv) {
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
  rayfarm::add_logging_options(app, logging);
  app.add_option("--heartbeat-ms", heartbeat_ms, "heartbeat interval in milliseconds")
      ->check(CLI::Range(int64_t{10}, int64_t{60000}))
      ->capture_default_str();
  app.add_option("--liveness", options.heartbeat.liveness,
                 "heartbeat intervals of silence before a worker is declared lost")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--image-interval-ms", image_interval_ms,
                 "rewrite a running job's image at least this often (milliseconds)")
      ->check(CLI::Range(int64_t{100}, int64_t{3600000}))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  logging.apply();
  options.data_dir = data_dir;
  options.heartbeat.interval = std::chrono::milliseconds{heartbeat_ms};
  options.image_interval = std::chrono::milliseconds{image_interval_ms};

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  try {
    rayfarm::master::Broker broker(options);
    broker.run(g_stop);
  } catch (const std::exception& e) {
    rayfarm::get_logger("master")->critical("{}", e.what());
    return 1;
  }
  return 0;
}
