// The worker's reactor: one thread that reads the master's messages, hands units to the unit
// runner (worker/unit_runner.h) once their bundle is in the cache (worker/bundle_cache.h), sends
// back what the runner finished, and keeps the connection (worker/connection.h) alive.
#include "worker/agent.h"

#include <algorithm>
#include <chrono>

#include <unistd.h>

#include "common/bundle/bundle.h"
#include "common/net/keys.h"
#include "common/protocol/codec.h"
#include "common/util/log.h"
#include "worker/bundle_cache.h"
#include "worker/connection.h"
#include "worker/unit_runner.h"

namespace rayfarm::worker {
namespace protocol = rayfarm::protocol;
namespace wire = rayfarm::wire;
using protocol::encode;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("worker"); }

AgentOptions with_defaults(AgentOptions options) {
  if (options.name.empty()) options.name = default_worker_name();
  return options;
}

wire::Hello worker_hello(const std::string& name, int threads) {
  wire::Hello hello;
  hello.set_role(wire::ROLE_WORKER);
  hello.set_name(name);
  hello.set_threads(static_cast<uint32_t>(threads));
  hello.set_build(protocol::kBuildVersion);
  return hello;
}

}  // namespace

std::string default_worker_name() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return std::string(host[0] ? host : "worker") + "-" + std::to_string(::getpid());
}

struct Agent::Impl {
  AgentOptions options;
  BundleCache bundles;  // first: creates the cache dir the runner reads scenes from
  UnitRunner runner;
  Connection master;
  bool stopping = false;
  size_t asked = 0;  // WorkRequests not answered yet
  std::atomic<uint64_t> units_done{0};

  explicit Impl(AgentOptions o)
      : options(with_defaults(std::move(o))),
        bundles(options.cache_dir),
        runner(options.threads, options.units_in_flight, options.cache_dir),
        master(options.master, options.curve, options.heartbeat,
               worker_hello(options.name, runner.threads())) {}

  /// What was asked of a master is forgotten when Hello is said again (it restarted, or declared
  /// this worker lost); units in hand still return their results.
  void forget_requests() {
    asked = 0;
    bundles.forget_requests();
  }

  /// Asks for units until `capacity` are asked for, waiting for their bundle, or rendering.
  void request_work() {
    if (!master.welcomed() || stopping) return;
    while (asked + runner.in_hand() + bundles.waiting() < runner.capacity()) {
      master.send(encode(wire::WorkRequest{}));
      ++asked;
    }
  }

  void fail_unit(const wire::WorkUnit& unit, const std::string& reason) {
    log()->error("job {} unit {} failed: {}", unit.job_id(), unit.unit_id(), reason);
    wire::UnitFailed failed;
    failed.set_job_id(unit.job_id());
    failed.set_unit_id(unit.unit_id());
    failed.set_reason(reason);
    master.send(encode(std::move(failed)));
  }

  void start_unit(const wire::WorkUnit& unit) {
    if (!is_bundle_hash(unit.bundle_hash())) {
      fail_unit(unit, "bad bundle hash '" + unit.bundle_hash() + "'");
      request_work();
      return;
    }
    if (bundles.has(unit.bundle_hash())) {
      runner.start(unit);
      return;
    }
    bundles.wait_for(unit);
    request_bundle();
  }

  /// Asks for the bundle the cache wants now, if any.
  void request_bundle() {
    if (auto hash = bundles.next_request()) {
      wire::BundleRequest request;
      request.set_hash(*hash);
      master.send(encode(std::move(request)));
    }
  }

  void on_bundle(const wire::BundleReply& reply) {
    BundleCache::Arrival arrival = bundles.on_reply(reply);
    if (!arrival.expected || arrival.later) return;
    for (auto& unit : arrival.units) {
      if (arrival.error.empty()) {
        runner.start(std::move(unit));
      } else {
        fail_unit(unit, arrival.error);
      }
    }
    request_bundle();
    request_work();
  }

  /// Sends what the runner finished (a result waits for the next Welcome when the master does
  /// not know this worker now) and asks for more work.
  void collect(std::vector<UnitRunner::Finished> finished) {
    for (auto& f : finished) {
      if (f.ok) {
        ++units_done;
        master.send_when_welcomed(encode(std::move(f.result)));
      } else {
        fail_unit(f.unit, f.error);
      }
    }
    request_work();
  }

  void handle(const net::Frames& frames) {
    protocol::Decoded msg;
    try {
      msg = protocol::decode(frames);
    } catch (const protocol::DecodeError& e) {
      log()->warn("ignored a bad message from the master: {}", e.what());
      return;
    }
    if (const auto* refusal = msg.as<wire::Refusal>()) {
      log()->error("the master at {} refused this worker: {}", options.master, refusal->reason());
      master.refuse();
      return;
    }
    if (!msg.version_ok()) {
      log()->error("the master at {} speaks protocol version {}, this worker {}", options.master,
                   msg.version, protocol::kProtocolVersion);
      master.refuse();
      return;
    }
    if (const auto* welcome = msg.as<wire::Welcome>()) {
      log()->info("connected to the master at {} ({}) as '{}' with {} threads", options.master,
                  welcome->build(), options.name, runner.threads());
      master.welcome();
      request_work();
    } else if (msg.as<wire::Heartbeat>()) {
      // liveness only
    } else if (const auto* unit = msg.as<wire::WorkUnit>()) {
      if (asked > 0) --asked;
      if (runner.in_hand() + bundles.waiting() >= runner.capacity()) {
        log()->warn("the master sent job {} unit {} beyond the {} units this worker takes at once",
                    unit->job_id(), unit->unit_id(), runner.capacity());
        fail_unit(*unit, "the worker has no room for another unit");
        return;
      }
      start_unit(*unit);
    } else if (const auto* reply = msg.as<wire::BundleReply>()) {
      on_bundle(*reply);
    } else if (const auto* error = msg.as<wire::Error>()) {
      log()->warn("the master says: {}", error->message());
      if (error->code() == wire::Error::UNKNOWN_WORKER && master.welcomed()) {
        // The master restarted (or declared us lost) and the connection came back by itself.
        forget_requests();
        master.greet_again();
      }
    } else {
      log()->warn("ignored an unexpected {} from the master", msg.type);
    }
  }

  /// Waits up to `wait` for a render to finish or a message to arrive, and handles what came.
  void wait_and_handle(milliseconds wait) {
    if (bundles.request_due()) {
      request_bundle();  // a bundle the master said to ask for again later
      wait = std::min(wait, milliseconds{100});
    }
    if (runner.in_hand() > 0) {
      // Wait on the renders themselves, so that a result leaves the moment it is ready; what the
      // master sent meanwhile (heartbeats) is read right after.
      collect(runner.take_finished(wait));
      wait = milliseconds{0};
    }
    if (auto frames = master.receive(wait)) {
      handle(*frames);
      while (!master.refused()) {
        auto more = master.receive(milliseconds{0});
        if (!more) break;
        handle(*more);
      }
    }
  }

  int run(const std::atomic<bool>& stop) {
    if (!options.curve.enabled()) {
      if (!net::is_loopback_endpoint(options.master)) {
        log()->error(
            "--insecure is allowed only with a master on loopback, and {} is not: give this "
            "worker its key and the master's public key (--key, --master-key)",
            options.master);
        return 1;
      }
      log()->warn("INSECURE: no authentication and no encryption to the master at {}",
                  options.master);
    }
    try {
      master.open();
    } catch (const net::NetError& e) {
      log()->error("{}", e.what());
      return 1;
    }
    Clock::time_point stop_deadline;
    bool abandoned = false;
    while (!master.refused()) {
      const size_t in_hand = runner.in_hand();
      if (stop.load() && !stopping) {
        stopping = true;
        stop_deadline = Clock::now() + options.stop_grace;
        if (in_hand == 0) {
          log()->info("stopping");
        } else {
          log()->info("stopping after the {} unit{} in hand", in_hand, in_hand == 1 ? "" : "s");
        }
      }
      if (stopping && in_hand == 0) break;
      if (stopping && Clock::now() >= stop_deadline) {
        log()->warn(
            "the {} unit{} in hand did not finish within {:g} s of the stop; the master "
            "takes {} back",
            in_hand, in_hand == 1 ? "" : "s",
            static_cast<double>(options.stop_grace.count()) / 1000.0, in_hand == 1 ? "it" : "them");
        abandoned = true;
        break;
      }

      wait_and_handle(std::clamp(master.until_heartbeat(), milliseconds{0}, milliseconds{100}));
      if (master.refused()) break;
      const auto now = Clock::now();
      master.tick(now);
      if (master.silent(now)) {
        master.reconnect([&] { return stop.load() && runner.in_hand() == 0; });
        forget_requests();
      }
    }
    // Refused mid-unit: let the renders end before the worker does.
    while (runner.in_hand() > 0 && !abandoned) collect(runner.take_finished());
    runner.log_job_stats();
    const bool refused = master.refused();
    master.close();
    log()->info("worker stopped after {} units", units_done.load());
    return refused ? 1 : 0;
  }
};

Agent::Agent(AgentOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}
Agent::~Agent() = default;

int Agent::run(const std::atomic<bool>& stop) { return impl_->run(stop); }

uint64_t Agent::units_rendered() const { return impl_->units_done.load(); }

uint64_t Agent::messages_dropped() const { return impl_->master.messages_dropped(); }

}  // namespace rayfarm::worker
