// The master's merge rate with a synthetic flood of results (no rendering). Prints two figures:
//   1. in process, no sockets: decode a UnitResult, check it, merge it into the film;
//   2. through a real Broker on loopback: fake workers ask for units and answer each at once with
//      a result of the right size, so the master's reactor (receive, decode, check, merge, the
//      progressive image after each pass, the next lease) is the only limit.
// Usage: farm_merge_bench [--workers N] [--size S] [--tile T] [--spp N] [--pass-spp P]
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

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

/// A result of the right shape for the unit, with non-trivial sums.
rayfarm::TileResult fake_result(const rayfarm::TileRect& rect,
                                const rayfarm::SampleRange& samples) {
  rayfarm::TileResult r(rect, samples);
  // Sums that samples could have (the master refuses impossible ones): mean m in [0.25, 0.31],
  // second moment m^2 + 0.01.
  const double n = samples.count();
  for (size_t i = 0; i < r.sum.size(); ++i) {
    const double m = 0.25 + 0.01 * static_cast<double>(i % 7);
    r.sum[i] = rayfarm::to_fixed(m * n);
    r.sum_sq[i] = rayfarm::to_fixed((m * m + 0.01) * n);
  }
  return r;
}

void bench_in_process(uint32_t size, uint32_t tile, uint32_t spp, uint32_t pass_spp) {
  const rayfarm::UnitGrid grid({size, size}, tile, spp, pass_spp);
  std::vector<rayfarm::net::Frames> messages;
  size_t bytes = 0;
  for (uint64_t u = 0; u < grid.size(); ++u) {
    const auto unit = grid.unit(u);
    messages.push_back(protocol::encode(
        protocol::result_to_wire("j", u, fake_result(unit.rect, unit.samples), 0.0)));
    bytes += messages.back()[1].size();
  }
  rayfarm::master::Merger merger(grid);
  const auto start = Clock::now();
  for (uint64_t u = 0; u < grid.size(); ++u) {
    const protocol::Decoded d = protocol::decode(messages[u]);
    const rayfarm::TileResult r = protocol::result_from_wire(*d.as<wire::UnitResult>());
    if (merger.add(u, r) != rayfarm::master::MergeOutcome::kMerged)
      throw std::runtime_error("merge failed");
  }
  const double s = seconds_since(start);
  std::cout << fmt::format(
      "in process (decode + check + merge, no sockets): {} units of {}x{} px ({:.1f} KB each) in "
      "{:.3f} s: "
      "{:.0f} units/s, {:.0f} MB/s\n",
      grid.size(), tile, tile, bytes / 1e3 / grid.size(), s, grid.size() / s, bytes / 1e6 / s);
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void fake_worker(const std::string& endpoint, int index, std::atomic<bool>& stop,
                 std::atomic<uint64_t>& sent) {
  rayfarm::net::Dealer socket(endpoint);
  wire::Hello hello;
  hello.set_role(wire::ROLE_WORKER);
  hello.set_name("flood-" + std::to_string(index));
  socket.send(protocol::encode(hello));
  socket.send(protocol::encode(wire::WorkRequest{}));
  // Sums packed once per tile shape, so that the fake workers cost little next to the master.
  std::map<std::pair<uint32_t, uint32_t>, std::string> packed;
  while (!stop.load()) {
    auto frames = socket.receive(milliseconds{50});
    if (!frames) continue;
    const protocol::Decoded d = protocol::decode(*frames);
    const auto* unit = d.as<wire::WorkUnit>();
    if (!unit) continue;  // Welcome, Heartbeat
    const rayfarm::TileRect rect = protocol::rect_from_wire(unit->tile());
    const rayfarm::SampleRange samples{unit->sample_begin(), unit->sample_end()};
    std::string& sums = packed[{rect.width(), rect.height()}];
    if (sums.empty()) sums = protocol::pack_fixed(fake_result(rect, samples).sum);
    wire::UnitResult result;
    result.set_job_id(unit->job_id());
    result.set_unit_id(unit->unit_id());
    *result.mutable_tile() = unit->tile();
    result.set_sample_begin(samples.begin);
    result.set_sample_end(samples.end);
    result.set_sum(sums);
    result.set_sum_sq(sums);
    socket.send(protocol::encode(std::move(result)));
    socket.send(protocol::encode(wire::WorkRequest{}));
    ++sent;
  }
}

void bench_broker(int workers, uint32_t size, uint32_t tile, uint32_t spp, uint32_t pass_spp) {
  const fs::path dir =
      fs::temp_directory_path() / ("rayfarm-merge-bench-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // The furnace scene with a bigger film; it is only parsed, never rendered.
  nlohmann::json scene =
      nlohmann::json::parse(read_text(fs::path(RAYFARM_SOURCE_DIR) / "scenes/furnace/scene.json"));
  scene["film"] = {{"width", size}, {"height", size}};
  const rayfarm::Bundle bundle = rayfarm::make_bundle({{"scene.json", scene.dump()}});

  rayfarm::master::MasterOptions options;
  options.worker_endpoint = "tcp://127.0.0.1:0";
  options.client_endpoint = "tcp://127.0.0.1:0";
  options.data_dir = dir / "data";
  options.image_interval = std::chrono::hours(1);  // images only after each pass, as in production
  rayfarm::master::Broker broker(options);
  std::atomic<bool> stop_master{false}, stop_workers{false};
  std::thread master([&] { broker.run(stop_master); });

  rayfarm::net::Dealer client(broker.client_endpoint());
  wire::SubmitJob submit;
  protocol::bundle_to_wire(bundle, submit.mutable_bundle());
  submit.set_scene_path("scene.json");
  submit.mutable_overrides()->set_spp(spp);
  submit.mutable_overrides()->set_tile_size(tile);
  submit.mutable_overrides()->set_pass_spp(pass_spp);
  client.send(protocol::encode(submit));
  auto reply = client.receive(milliseconds{10000});
  const std::string job = reply ? protocol::decode(*reply).as<wire::SubmitReply>()->job_id() : "";
  if (job.empty()) {
    stop_master = true;
    master.join();
    throw std::runtime_error("the job was not accepted");
  }

  std::atomic<uint64_t> sent{0};
  const auto start = Clock::now();
  std::vector<std::thread> threads;
  for (int i = 0; i < workers; ++i) {
    threads.emplace_back(fake_worker, broker.worker_endpoint(), i, std::ref(stop_workers),
                         std::ref(sent));
  }
  // The threads stop on every way out, also when the master stops answering.
  const auto stop_all = [&] {
    stop_workers = true;
    for (auto& t : threads) t.join();
    threads.clear();
    stop_master = true;
    if (master.joinable()) master.join();
  };
  wire::JobStatus status;
  std::string error;
  while (error.empty()) {
    wire::StatusRequest request;
    request.set_job_id(job);
    client.send(protocol::encode(request));
    auto frames = client.receive(milliseconds{30000});
    if (!frames) {
      error = "no status from the master within 30 s";
      break;
    }
    status = *protocol::decode(*frames).as<wire::JobStatus>();
    if (status.state() == wire::JOB_DONE) break;
    if (seconds_since(start) > 600) error = "the job did not finish within 600 s";
    std::this_thread::sleep_for(milliseconds{20});
  }
  stop_all();
  if (!error.empty()) throw std::runtime_error(error);
  const double s = status.elapsed_seconds();
  // What the fake workers send: the packed sums of a full tile, twice (sum and sum_sq).
  const double unit_kb =
      2.0 *
      static_cast<double>(
          protocol::pack_fixed(fake_result(rayfarm::TileRect{0, 0, tile, tile}, {0, pass_spp}).sum)
              .size()) /
      1e3;
  std::cout << fmt::format(
      "through the broker ({} fake workers on loopback): {} units of {}x{} px ({:.1f} KB each) in "
      "{:.3f} s: "
      "{:.0f} units/s, {:.0f} MB/s, including {} progressive EXR+PNG writes of {}x{}\n",
      workers, status.units_total(), tile, tile, unit_kb, s, status.units_total() / s,
      status.units_total() * unit_kb / 1e3 / s, status.passes_total(), size, size);
  std::error_code ec;
  fs::remove_all(dir, ec);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"farm_merge_bench: the master's merge rate with synthetic results"};
  int workers = 4;
  uint32_t size = 1024, tile = 64, spp = 16, pass_spp = 4;
  app.add_option("--workers", workers, "fake workers flooding the master")->capture_default_str();
  app.add_option("--size", size, "film width and height")->capture_default_str();
  app.add_option("--tile", tile, "tile size")->capture_default_str();
  app.add_option("--spp", spp, "samples per pixel")->capture_default_str();
  app.add_option("--pass-spp", pass_spp, "samples per pass")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  rayfarm::configure_logging("warn");
  try {
    bench_in_process(size, tile, spp, pass_spp);
    bench_broker(workers, size, tile, spp, pass_spp);
  } catch (const std::exception& e) {
    std::cerr << "farm_merge_bench: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
