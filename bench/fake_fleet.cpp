#include "bench/fake_fleet.h"

#include <sys/resource.h>

#include <algorithm>
#include <iterator>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <stdexcept>

#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "common/image/fixed.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"

namespace rayfarm::bench {
namespace protocol = rayfarm::protocol;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

TileResult fake_result(const TileRect& rect, const SampleRange& samples) {
  TileResult r(rect, samples);
  const double n = samples.count();
  for (size_t i = 0; i < r.sum.size(); ++i) {
    const double m = 0.25 + 0.01 * static_cast<double>(i % 7);
    r.sum[i] = to_fixed(m * n);
    r.sum_sq[i] = to_fixed((m * m + 0.01) * n);
  }
  return r;
}

namespace {

constexpr auto kHeartbeat = std::chrono::seconds{1};

/// Raises the soft open-file limit to what `workers` connections need (each takes a TCP socket
/// and a mailbox on this side, and a TCP socket on the master's), up to the hard limit.
void raise_file_limit(int workers) {
  rlimit limit{};
  if (::getrlimit(RLIMIT_NOFILE, &limit) != 0) return;
  const rlim_t need = 4 * static_cast<rlim_t>(workers) + 256;
  if (limit.rlim_cur != RLIM_INFINITY && limit.rlim_cur < need) {
    limit.rlim_cur = limit.rlim_max == RLIM_INFINITY ? need : std::min(need, limit.rlim_max);
    ::setrlimit(RLIMIT_NOFILE, &limit);
  }
  if (::getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY &&
      limit.rlim_cur < need) {
    throw std::runtime_error("the open-file limit (ulimit -n) is too low for this many workers");
  }
}

void send_frames(zmq::socket_t& socket, const net::Frames& frames) {
  std::vector<zmq::const_buffer> parts;
  for (const std::string& f : frames) parts.push_back(zmq::buffer(f));
  zmq::send_multipart(socket, parts, zmq::send_flags::dontwait);
}

struct Worker {
  zmq::socket_t socket;
  std::optional<wire::WorkUnit> unit;  // leased, its result not sent yet
  Clock::time_point due;               // when its result goes
  Clock::time_point last_sent;
  bool first = true;
};

}  // namespace

struct FakeFleet::Impl {
  zmq::context_t context;
  std::vector<std::vector<Worker>> groups;  // one per thread
};

namespace {

void serve_until_stopped(std::vector<Worker>& workers, const FleetOptions& options, unsigned seed,
                         const std::atomic<bool>& stop, FleetCounters& counters) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> phase(0.0, 1.0);
  std::vector<zmq::pollitem_t> items;
  for (Worker& w : workers) items.push_back({w.socket.handle(), 0, ZMQ_POLLIN, 0});
  // Sums packed once per tile shape, so that the fake workers cost little next to the master.
  std::map<std::pair<uint32_t, uint32_t>, std::string> packed;
  const net::Frames request = protocol::encode(wire::WorkRequest{});
  const net::Frames heartbeat = protocol::encode(wire::Heartbeat{});
  while (!stop.load()) {
    auto now = Clock::now();
    Clock::time_point next = now + milliseconds{50};
    for (const Worker& w : workers) {
      if (w.unit) next = std::min(next, w.due);
    }
    const auto wait = std::chrono::ceil<milliseconds>(std::max(next - now, Clock::duration{}));
    zmq::poll(items, wait);
    now = Clock::now();
    for (size_t i = 0; i < workers.size(); ++i) {
      Worker& w = workers[i];
      if (items[i].revents & ZMQ_POLLIN) {
        std::vector<zmq::message_t> parts;
        while (
            zmq::recv_multipart(w.socket, std::back_inserter(parts), zmq::recv_flags::dontwait)) {
          net::Frames frames;
          for (const auto& p : parts) frames.push_back(p.to_string());
          parts.clear();
          protocol::Decoded d = protocol::decode(frames);
          auto* unit = d.as_mutable<wire::WorkUnit>();
          if (!unit) continue;  // Welcome, Heartbeat
          ++counters.units;
          double seconds = options.unit_seconds;
          if (w.first) {
            ++counters.connected;
            seconds *= phase(random);  // spread the workers' phases
            w.first = false;
          }
          w.unit = std::move(*unit);
          w.due = now + std::chrono::duration_cast<Clock::duration>(
                            std::chrono::duration<double>(seconds));
        }
      }
      if (w.unit && w.due <= now) {
        const wire::WorkUnit& unit = *w.unit;
        const TileRect rect = protocol::rect_from_wire(unit.tile());
        const SampleRange samples{unit.sample_begin(), unit.sample_end()};
        std::string& sums = packed[{rect.width(), rect.height()}];
        if (sums.empty()) sums = protocol::pack_fixed(fake_result(rect, samples).sum);
        wire::UnitResult result;
        result.set_job_id(unit.job_id());
        result.set_unit_id(unit.unit_id());
        *result.mutable_tile() = unit.tile();
        result.set_sample_begin(samples.begin);
        result.set_sample_end(samples.end);
        result.set_sum(sums);
        result.set_sum_sq(sums);
        result.set_render_seconds(options.unit_seconds);
        const net::Frames frames = protocol::encode(std::move(result));
        send_frames(w.socket, frames);
        send_frames(w.socket, request);
        w.unit.reset();
        w.last_sent = now;
        ++counters.results;
        counters.bytes += frames[0].size() + frames[1].size();
      } else if (now - w.last_sent >= kHeartbeat) {
        send_frames(w.socket, heartbeat);
        w.last_sent = now;
      }
    }
  }
}

/// A thread that fails says why in `counters.error`; the bench reads it and stops.
void serve(std::vector<Worker>& workers, const FleetOptions& options, unsigned seed,
           const std::atomic<bool>& stop, FleetCounters& counters) {
  try {
    serve_until_stopped(workers, options, seed, stop, counters);
  } catch (const std::exception& e) {
    std::lock_guard lock(counters.mutex);
    counters.error = e.what();
  }
}

}  // namespace

FakeFleet::FakeFleet(const std::string& endpoint, const FleetOptions& options)
    : impl_(std::make_unique<Impl>()) {
  raise_file_limit(options.workers);
  impl_->context.set(zmq::ctxopt::max_sockets, options.workers + 64);
  const int threads = std::clamp(options.threads, 1, std::max(options.workers, 1));
  impl_->groups.resize(threads);
  const net::Frames request = protocol::encode(wire::WorkRequest{});
  for (int i = 0; i < options.workers; ++i) {
    Worker w;
    w.socket = zmq::socket_t(impl_->context, zmq::socket_type::dealer);
    w.socket.set(zmq::sockopt::linger, 0);
    w.socket.connect(endpoint);
    wire::Hello hello;
    hello.set_role(wire::ROLE_WORKER);
    hello.set_name("flood-" + std::to_string(i));
    hello.set_threads(1);
    send_frames(w.socket, protocol::encode(hello));
    send_frames(w.socket, request);
    w.last_sent = Clock::now();
    impl_->groups[i % threads].push_back(std::move(w));
  }
  for (int t = 0; t < threads; ++t) {
    threads_.emplace_back(serve, std::ref(impl_->groups[t]), options, 1234u + t, std::cref(stop_),
                          std::ref(counters_));
  }
}

FakeFleet::~FakeFleet() {
  stop_ = true;
  for (auto& t : threads_) t.join();
  impl_.reset();  // sockets first (linger 0), then the context
}

}  // namespace rayfarm::bench
