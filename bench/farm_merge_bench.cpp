// The master's merge rate with a synthetic flood of results (no rendering). Prints two figures:
//   1. in process, no sockets: decode a UnitResult, check it, merge it into the film;
//   2. through a real Broker on loopback: fake workers (fake_fleet.h, one connection each) ask
//      for units and answer each with a result of the right size, at once (flat out: the master's
//      reactor -- receive, decode, check, merge, the progressive image after each pass, the next
//      lease -- is the only limit) or `--unit-seconds` after the lease (paced: the load a farm of
//      that many workers offers). Reported: results merged per second, MB/s received, and the
//      reactor's busy fraction (its time outside the poll wait over wall time) and its thread's
//      CPU time over wall time.
// With --seconds S the figures are those of a window of S seconds after a warm-up (the job must
// last that long: raise --spp); without, of the whole job.
// Usage: farm_merge_bench [--workers N] [--worker-threads T] [--unit-seconds U] [--seconds S]
//                         [--warmup W] [--size S] [--tile T] [--spp N] [--pass-spp P]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <mutex>
#include <optional>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <httplib.h>
#include <pthread.h>
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench/fake_fleet.h"
#include "common/bundle/bundle.h"
#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/util/log.h"
#include "master/broker.h"
#include "master/merger.h"

namespace {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;
namespace wire = rayfarm::wire;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

void bench_in_process(uint32_t size, uint32_t tile, uint32_t spp, uint32_t pass_spp) {
  const rayfarm::UnitGrid grid({size, size}, tile, spp, pass_spp);
  // At most the first 4096 units: their messages are held in memory at once.
  const uint64_t units = std::min<uint64_t>(grid.size(), 4096);
  std::vector<rayfarm::net::Frames> messages;
  size_t bytes = 0;
  for (uint64_t u = 0; u < units; ++u) {
    const auto unit = grid.unit(u);
    messages.push_back(protocol::encode(protocol::result_to_wire(
        "j", u, rayfarm::bench::fake_result(unit.rect, unit.samples), 0.0)));
    bytes += messages.back()[1].size();
  }
  rayfarm::master::Merger merger(grid);
  const auto start = Clock::now();
  for (uint64_t u = 0; u < units; ++u) {
    const protocol::Decoded d = protocol::decode(messages[u]);
    const rayfarm::TileResult r = protocol::result_from_wire(*d.as<wire::UnitResult>());
    if (merger.add(u, r) != rayfarm::master::MergeOutcome::kMerged)
      throw std::runtime_error("merge failed");
  }
  const double s = seconds_since(start);
  std::cout << fmt::format(
      "in process (decode + check + merge, no sockets): {} units of {}x{} px ({:.1f} KB each) in "
      "{:.3f} s: {:.0f} units/s, {:.0f} MB/s\n",
      units, tile, tile, bytes / 1e3 / units, s, units / s, bytes / 1e6 / s);
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct BrokerRun {
  int workers = 4;
  int worker_threads = 2;
  double unit_seconds = 0;  // 0: flat out
  double seconds = 0;       // the measured window; 0: the whole job
  double warmup = -1;       // before the window; negative: chosen from the mode
  uint32_t size = 1024, tile = 64, spp = 16, pass_spp = 4;
  int http_pollers = 0;         // dashboard pages polling the master's HTTP endpoint
  int http_interval_ms = 1000;  // each page's round: jobs, workers, the job's detail, metrics
};

/// Pages polling the master's HTTP endpoint, as the dashboard and Prometheus do: each a round of
/// /api/jobs, /api/workers, the job's detail view (/api/jobs/JOB/detail, which the reactor
/// answers) and /metrics every interval, on threads of their own.
class HttpPollers {
 public:
  HttpPollers(const std::string& url, const std::string& job, int pollers, int interval_ms) {
    for (int i = 0; i < pollers; ++i) {
      threads_.emplace_back([this, url, job, interval_ms] {
        httplib::Client c(url.substr(0, url.size() - 1));
        c.set_keep_alive(true);
        const std::string detail = "/api/jobs/" + job + "/detail";
        while (!stop_) {
          const auto next = Clock::now() + milliseconds{interval_ms};
          for (const std::string& path : {std::string("/api/jobs"), std::string("/api/workers"),
                                          detail, std::string("/metrics")}) {
            auto res = c.Get(path);
            if (res && res->status == 200) {
              ++ok_;
            } else {
              ++failed_;
            }
          }
          std::this_thread::sleep_until(next);
        }
      });
    }
  }
  ~HttpPollers() {
    stop_ = true;
    for (auto& t : threads_) t.join();
  }
  uint64_t ok() const { return ok_; }
  uint64_t failed() const { return failed_; }

 private:
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> ok_{0}, failed_{0};
  std::vector<std::thread> threads_;
};

/// What is counted at each end of the measured window.
struct Sample {
  Clock::time_point at;
  double busy = 0;    // the reactor's time outside its poll wait
  double cpu = 0;     // the reactor thread's CPU time
  double queued = 0;  // and its time waiting for a CPU
  uint64_t polls = 0;
  uint64_t merged = 0;  // units merged, as the job's status says
  uint64_t sent = 0;    // results the fake workers sent
  uint64_t bytes = 0;   // their bytes
  uint64_t http = 0;    // HTTP requests answered 200
};

/// A thread's time on a CPU and waiting for one (runnable but not running), from Linux's
/// /proc/self/task/TID/schedstat; zeros where it cannot be read.
std::pair<double, double> thread_schedstat(pid_t tid) {
  std::ifstream in("/proc/self/task/" + std::to_string(tid) + "/schedstat");
  double cpu_ns = 0, wait_ns = 0;
  if (!(in >> cpu_ns >> wait_ns)) return {0.0, 0.0};
  return {cpu_ns / 1e9, wait_ns / 1e9};
}

void bench_broker(const BrokerRun& run) {
  const fs::path dir =
      fs::temp_directory_path() / ("rayfarm-merge-bench-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // The furnace scene with a bigger film; it is only parsed, never rendered.
  nlohmann::json scene =
      nlohmann::json::parse(read_text(fs::path(RAYFARM_SOURCE_DIR) / "scenes/furnace/scene.json"));
  scene["film"] = {{"width", run.size}, {"height", run.size}};
  const rayfarm::Bundle bundle = rayfarm::make_bundle({{"scene.json", scene.dump()}});

  rayfarm::master::MasterOptions options;
  options.worker_endpoint = "tcp://127.0.0.1:0";
  options.client_endpoint = "tcp://127.0.0.1:0";
  options.data_dir = dir / "data";
  if (run.http_pollers > 0) options.http_endpoint = "127.0.0.1:0";
  // The master's defaults: an image and a checkpoint after a round of passes, at most every 3 s
  // and every 2 s.
  rayfarm::master::Broker broker(options);
  std::atomic<bool> stop_master{false};
  std::atomic<pid_t> master_tid{0};
  std::thread master([&] {
    master_tid = ::gettid();
    ::pthread_setname_np(::pthread_self(), "reactor");  // for profilers: perf report --comm
    broker.run(stop_master);
  });

  rayfarm::net::Dealer client(broker.client_endpoint());
  wire::SubmitJob submit;
  protocol::bundle_to_wire(bundle, submit.mutable_bundle());
  submit.set_scene_path("scene.json");
  submit.mutable_overrides()->set_spp(run.spp);
  submit.mutable_overrides()->set_tile_size(run.tile);
  submit.mutable_overrides()->set_pass_spp(run.pass_spp);
  client.send(protocol::encode(submit));
  auto reply = client.receive(milliseconds{10000});
  const std::string job = reply ? protocol::decode(*reply).as<wire::SubmitReply>()->job_id() : "";
  if (job.empty()) {
    stop_master = true;
    master.join();
    throw std::runtime_error("the job was not accepted");
  }
  const auto status = [&]() -> wire::JobStatus {
    wire::StatusRequest request;
    request.set_job_id(job);
    client.send(protocol::encode(request));
    auto frames = client.receive(milliseconds{30000});
    if (!frames) throw std::runtime_error("no status from the master within 30 s");
    return *protocol::decode(*frames).as<wire::JobStatus>();
  };

  std::optional<rayfarm::bench::FakeFleet> fleet;
  std::optional<HttpPollers> pollers;
  // The master and the fleet stop on every way out, also when the master stops answering; the
  // master first, so that it does not see its workers vanish.
  const auto stop_all = [&] {
    pollers.reset();
    stop_master = true;
    if (master.joinable()) master.join();
    fleet.reset();
  };
  const auto sample = [&](uint64_t merged) {
    Sample out{Clock::now(), broker.busy_seconds()};
    std::tie(out.cpu, out.queued) = thread_schedstat(master_tid.load());
    out.polls = broker.polls();
    out.merged = merged;
    if (fleet) {
      out.sent = fleet->counters().results.load();
      out.bytes = fleet->counters().bytes.load();
    }
    if (pollers) out.http = pollers->ok();
    return out;
  };
  const auto fleet_error = [&] {
    std::lock_guard lock(fleet->counters().mutex);
    return fleet->counters().error;
  };
  std::string error;
  Sample first, last;
  wire::JobStatus st;
  try {
    const Sample before = sample(0);
    fleet.emplace(broker.worker_endpoint(),
                  rayfarm::bench::FleetOptions{run.workers, run.worker_threads, run.unit_seconds});
    if (run.http_pollers > 0)
      pollers.emplace(broker.http_url(), job, run.http_pollers, run.http_interval_ms);
    first = before;
    if (run.seconds > 0) {
      const double warmup = run.warmup >= 0 ? run.warmup : std::max(2.0, 1.5 * run.unit_seconds);
      std::this_thread::sleep_for(std::chrono::duration<double>(warmup));
      first = sample(status().units_done());
    }
    const Clock::time_point end = first.at + std::chrono::duration_cast<Clock::duration>(
                                                 std::chrono::duration<double>(run.seconds));
    while (error.empty()) {
      if (run.seconds > 0) {
        std::this_thread::sleep_until(std::min(end, Clock::now() + milliseconds{250}));
      } else {
        std::this_thread::sleep_for(milliseconds{20});
      }
      st = status();
      if (std::string e = fleet_error(); !e.empty()) error = "a fake worker failed: " + e;
      if (run.seconds > 0 && Clock::now() >= end) {
        if (st.state() == wire::JOB_DONE) error = "the job finished inside the window: raise --spp";
        break;
      }
      if (st.state() == wire::JOB_DONE) break;
      if (seconds_since(first.at) > 600) error = "the job did not finish within 600 s";
    }
    last = sample(run.seconds > 0 ? st.units_done() : st.units_total());
  } catch (const std::exception& e) {
    error = e.what();
  }
  const uint64_t connected = fleet ? fleet->counters().connected.load() : 0;
  const uint64_t http_failed = pollers ? pollers->failed() : 0;
  stop_all();
  std::error_code ec;
  fs::remove_all(dir, ec);
  if (!error.empty()) throw std::runtime_error(error);

  const double wall = std::chrono::duration<double>(last.at - first.at).count();
  // What the fake workers send: the packed sums of a full tile, twice (sum and sum_sq).
  const rayfarm::TileRect full{0, 0, run.tile, run.tile};
  const std::string sums =
      protocol::pack_fixed(rayfarm::bench::fake_result(full, {0, run.pass_spp}).sum);
  const double unit_kb = 2.0 * static_cast<double>(sums.size()) / 1e3;
  const std::string offered =
      run.unit_seconds > 0
          ? fmt::format("{:.0f} results/s offered ({} workers / {} s a unit)",
                        run.workers / run.unit_seconds, run.workers, run.unit_seconds)
          : "flat out";
  const std::string window =
      run.seconds > 0 ? fmt::format("a window of {:.1f} s", wall)
                      : fmt::format(
                            "the whole job, {} units in {:.3f} s ({:.3f} s on the master's clock: "
                            "{:.0f} units/s)",
                            st.units_total(), wall, st.elapsed_seconds(),
                            st.units_total() / st.elapsed_seconds());
  std::cout << fmt::format(
      "through the broker ({} fake workers on loopback, {}; {} got a unit, {} still connected "
      "at the end), {}x{} px units "
      "({:.1f} KB each), {}x{} image, {} passes of {} spp; over {}:\n"
      "  merged {:.0f} results/s, received {:.1f} MB/s (the workers sent {:.0f} results/s)\n"
      "  reactor busy {:.3f} of wall time (on a CPU {:.3f}, waiting for one {:.3f}), {:.0f} "
      "polls/s\n",
      run.workers, offered, connected, st.workers_total(), run.tile, run.tile, unit_kb, run.size,
      run.size, st.passes_total(), run.pass_spp, window, (last.merged - first.merged) / wall,
      (last.bytes - first.bytes) / 1e6 / wall, (last.sent - first.sent) / wall,
      (last.busy - first.busy) / wall, (last.cpu - first.cpu) / wall,
      (last.queued - first.queued) / wall, (last.polls - first.polls) / wall);
  if (run.http_pollers > 0) {
    std::cout << fmt::format(
        "  HTTP: {} pages polling every {} ms: {:.0f} requests/s answered, {} failed\n",
        run.http_pollers, run.http_interval_ms, (last.http - first.http) / wall, http_failed);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"farm_merge_bench: the master's merge rate with synthetic results"};
  BrokerRun run;
  app.add_option("--workers", run.workers, "fake workers (one connection each)")
      ->capture_default_str();
  app.add_option("--worker-threads", run.worker_threads, "threads the fake workers share")
      ->capture_default_str();
  app.add_option("--unit-seconds", run.unit_seconds,
                 "each fake worker returns a result this long after its lease (0: at once)")
      ->capture_default_str();
  app.add_option("--seconds", run.seconds, "measure a window this long (0: the whole job)")
      ->capture_default_str();
  app.add_option("--warmup", run.warmup,
                 "before the window (default: 2 s or 1.5 units, whichever is longer)");
  app.add_option("--size", run.size, "film width and height")->capture_default_str();
  app.add_option("--tile", run.tile, "tile size")->capture_default_str();
  app.add_option("--spp", run.spp, "samples per pixel")->capture_default_str();
  app.add_option("--pass-spp", run.pass_spp, "samples per pass")->capture_default_str();
  app.add_option("--http-pollers", run.http_pollers,
                 "pages polling the master's HTTP endpoint (/api/jobs, /api/workers, the job's "
                 "detail, /metrics)")
      ->capture_default_str();
  app.add_option("--http-interval-ms", run.http_interval_ms, "each page's polling interval")
      ->capture_default_str();
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "the master's log level")->capture_default_str();
  bool skip_in_process = false;
  app.add_flag("--no-in-process", skip_in_process, "skip the in-process figure");
  CLI11_PARSE(app, argc, argv);
  rayfarm::configure_logging(log_level);
  try {
    if (!skip_in_process) bench_in_process(run.size, run.tile, run.spp, run.pass_spp);
    bench_broker(run);
  } catch (const std::exception& e) {
    std::cerr << "farm_merge_bench: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
