#include "worker/agent.h"

#include <algorithm>
#include <chrono>
#include <future>
#include <optional>
#include <system_error>
#include <thread>

#include <tbb/task_arena.h>
#include <unistd.h>

#include "common/bundle/bundle.h"
#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/parser.h"
#include "common/util/log.h"
#include "worker/renderer.h"

namespace rayfarm::worker {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;
namespace wire = rayfarm::wire;
using protocol::encode;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("worker"); }

/// How long a stopping worker waits for its last messages to leave.
constexpr milliseconds kFinalLinger{2000};

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

/// The scene and renderer of one job, identified by everything they depend on.
struct Loaded {
  std::string key;
  std::string job_id;
  std::unique_ptr<Scene> scene;  // outlives the renderer built from it
  std::unique_ptr<Renderer> renderer;
  uint64_t units = 0;
  uint64_t samples = 0;
  double render_seconds = 0.0;
};

/// What the render thread hands back: a result or the reason it failed.
struct Outcome {
  wire::UnitResult result;
  std::string error;
  bool ok = false;
};

std::string unit_key(const wire::WorkUnit& unit) {
  return unit.job_id() + '\0' + unit.bundle_hash() + '\0' + unit.scene_path() + '\0' +
         unit.settings().SerializeAsString();
}

}  // namespace

std::string default_worker_name() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return std::string(host[0] ? host : "worker") + "-" + std::to_string(::getpid());
}

struct Agent::Impl {
  AgentOptions options;
  tbb::task_arena arena;
  std::unique_ptr<net::Dealer> socket;
  bool welcomed = false;
  bool refused = false;
  Clock::time_point last_heard;
  Clock::time_point next_heartbeat;
  milliseconds backoff;

  bool asked = false;                          // a WorkRequest is outstanding
  std::optional<wire::WorkUnit> needs_bundle;  // a unit waiting for its bundle
  std::optional<wire::WorkUnit> rendering;     // the unit in flight
  std::future<Outcome> render;
  std::optional<net::Frames> outbox;  // a result to send once welcomed again
  Loaded loaded;                      // touched by the render thread only while one runs
  std::atomic<uint64_t> units_done{0};

  explicit Impl(AgentOptions o)
      : options(std::move(o)),
        arena(options.threads == 0 ? tbb::task_arena::automatic
                                   : static_cast<int>(options.threads)),
        backoff(options.heartbeat.reconnect_min) {
    if (options.name.empty()) options.name = default_worker_name();
    std::error_code ec;
    fs::create_directories(options.cache_dir, ec);
    if (ec) {
      throw std::runtime_error("cannot create cache dir " + options.cache_dir.string() + ": " +
                               ec.message());
    }
  }

  int threads() const { return arena.max_concurrency(); }

  void send(const net::Frames& frames) {
    if (socket && !socket->send(frames))
      log()->warn("send queue to the master is full; message dropped");
  }

  void connect() {
    socket = std::make_unique<net::Dealer>(options.master);
    welcomed = false;
    asked = false;
    last_heard = Clock::now();
    next_heartbeat = last_heard + options.heartbeat.interval;
    say_hello();
  }

  void say_hello() {
    wire::Hello hello;
    hello.set_role(wire::ROLE_WORKER);
    hello.set_name(options.name);
    hello.set_threads(static_cast<uint32_t>(threads()));
    hello.set_build(protocol::kBuildVersion);
    welcomed = false;
    send(encode(std::move(hello)));
  }

  void request_work() {
    if (asked || rendering || needs_bundle || !welcomed) return;
    send(encode(wire::WorkRequest{}));
    asked = true;
  }

  void fail_unit(const wire::WorkUnit& unit, const std::string& reason) {
    log()->error("job {} unit {} failed: {}", unit.job_id(), unit.unit_id(), reason);
    wire::UnitFailed failed;
    failed.set_job_id(unit.job_id());
    failed.set_unit_id(unit.unit_id());
    failed.set_reason(reason);
    send(encode(std::move(failed)));
  }

  // --- Rendering (runs on the render thread) ---

  void prepare(const wire::WorkUnit& unit) {
    const std::string key = unit_key(unit);
    if (loaded.key == key) return;
    finish_job_log();
    const auto start = Clock::now();
    const fs::path scene_file = options.cache_dir / unit.bundle_hash() / unit.scene_path();
    auto scene = std::make_unique<Scene>(load_scene(scene_file));
    const RenderSettings settings = protocol::settings_from_wire(unit.settings());
    std::unique_ptr<Renderer> renderer;
    arena.execute([&] { renderer = std::make_unique<Renderer>(*scene, settings); });
    loaded = Loaded{key, unit.job_id(), std::move(scene), std::move(renderer)};
    log()->info(
        "job {}: {} {}x{}, {} spp, {}, seed {}; renderer ready in {:.2f} s ({} threads): {}",
        unit.job_id(), unit.scene_path(), loaded.scene->film.width, loaded.scene->film.height,
        settings.spp, integrator_name(settings.integrator), settings.seed, seconds_since(start),
        threads(), loaded.renderer->plan());
  }

  void finish_job_log() {
    if (loaded.key.empty() || loaded.units == 0) return;
    log()->info("job {}: rendered {} units, {:.3g} samples in {:.2f} s", loaded.job_id,
                loaded.units, static_cast<double>(loaded.samples), loaded.render_seconds);
  }

  Outcome render_unit(const wire::WorkUnit& unit) {
    Outcome out;
    try {
      prepare(unit);
      const TileRect rect = protocol::rect_from_wire(unit.tile());
      if (unit.sample_end() <= unit.sample_begin())
        throw protocol::ProtocolError("empty sample range");
      const SampleRange samples{unit.sample_begin(), unit.sample_end()};
      const auto start = Clock::now();
      TileResult result;
      arena.execute([&] { result = loaded.renderer->render(rect, samples); });
      const double seconds = seconds_since(start);
      ++loaded.units;
      loaded.samples += uint64_t{rect.pixel_count()} * samples.count();
      loaded.render_seconds += seconds;
      log()->debug("job {} unit {} (pass {}): tile [{},{})x[{},{}) samples [{},{}) in {:.3f} s",
                   unit.job_id(), unit.unit_id(), unit.pass(), rect.x0, rect.x1, rect.y0, rect.y1,
                   samples.begin, samples.end, seconds);
      out.result = protocol::result_to_wire(unit.job_id(), unit.unit_id(), result, seconds);
      out.ok = true;
    } catch (const std::exception& e) {
      loaded = Loaded{};  // a failed load leaves nothing half built behind
      out.error = e.what();
    }
    return out;
  }

  // --- The reactor (this thread) ---

  void start_unit(const wire::WorkUnit& unit) {
    if (!is_bundle_hash(unit.bundle_hash())) {
      fail_unit(unit, "bad bundle hash '" + unit.bundle_hash() + "'");
      request_work();
      return;
    }
    std::error_code ec;
    if (!fs::is_directory(options.cache_dir / unit.bundle_hash(), ec)) {
      log()->info("job {}: fetching bundle {} from the master", unit.job_id(),
                  unit.bundle_hash().substr(0, 12));
      wire::BundleRequest request;
      request.set_hash(unit.bundle_hash());
      send(encode(std::move(request)));
      needs_bundle = unit;
      return;
    }
    rendering = unit;
    render = std::async(std::launch::async, [this, unit] { return render_unit(unit); });
  }

  void on_bundle(const wire::BundleReply& reply) {
    if (!needs_bundle || reply.hash() != needs_bundle->bundle_hash()) {
      log()->debug("ignored an unrequested bundle {}", reply.hash().substr(0, 12));
      return;
    }
    const wire::WorkUnit unit = std::move(*needs_bundle);
    needs_bundle.reset();
    if (!reply.error().empty()) {
      fail_unit(unit, reply.error());
      request_work();
      return;
    }
    try {
      const Bundle bundle = protocol::bundle_from_wire(reply.bundle());
      const fs::path dir = unpack_bundle(bundle, options.cache_dir, unit.bundle_hash());
      log()->info("bundle {} cached in {} ({} files)", unit.bundle_hash().substr(0, 12),
                  dir.string(), bundle.files.size());
    } catch (const std::exception& e) {
      fail_unit(unit, std::string("cannot unpack the bundle: ") + e.what());
      request_work();
      return;
    }
    start_unit(unit);
  }

  void collect_render(bool stopping) {
    Outcome outcome = render.get();
    const wire::WorkUnit unit = std::move(*rendering);
    rendering.reset();
    if (outcome.ok) {
      ++units_done;
      net::Frames frames = encode(std::move(outcome.result));
      if (welcomed) {
        send(frames);
      } else {
        outbox = std::move(frames);  // sent after the next Welcome
      }
    } else {
      fail_unit(unit, outcome.error);
    }
    if (!stopping) request_work();
  }

  void handle(const net::Frames& frames, const std::atomic<bool>& stop) {
    protocol::Decoded msg;
    try {
      msg = protocol::decode(frames);
    } catch (const protocol::DecodeError& e) {
      log()->warn("ignored a bad message from the master: {}", e.what());
      return;
    }
    if (const auto* refusal = msg.as<wire::Refusal>()) {
      log()->error("the master at {} refused this worker: {}", options.master, refusal->reason());
      refused = true;
      return;
    }
    if (!msg.version_ok()) {
      log()->error("the master at {} speaks protocol version {}, this worker {}", options.master,
                   msg.version, protocol::kProtocolVersion);
      refused = true;
      return;
    }
    if (const auto* welcome = msg.as<wire::Welcome>()) {
      log()->info("connected to the master at {} ({}) as '{}' with {} threads", options.master,
                  welcome->build(), options.name, threads());
      welcomed = true;
      backoff = options.heartbeat.reconnect_min;
      if (outbox) {
        send(*outbox);
        outbox.reset();
      }
      if (!stop.load()) request_work();
    } else if (msg.as<wire::Heartbeat>()) {
      // liveness only
    } else if (const auto* unit = msg.as<wire::WorkUnit>()) {
      asked = false;
      if (rendering || needs_bundle) {
        log()->warn("the master sent job {} unit {} while another is in hand; refusing it",
                    unit->job_id(), unit->unit_id());
        fail_unit(*unit, "the worker already has a unit in hand");
        return;
      }
      start_unit(*unit);
    } else if (const auto* reply = msg.as<wire::BundleReply>()) {
      on_bundle(*reply);
    } else if (const auto* error = msg.as<wire::Error>()) {
      log()->warn("the master says: {}", error->message());
      if (error->message().rfind("unknown worker", 0) == 0 && welcomed) {
        // The master restarted (or declared us lost) and the connection came back by itself:
        // start over. What we asked for went to the old master; a unit in hand still returns.
        asked = false;
        needs_bundle.reset();
        say_hello();
      }
    } else {
      log()->warn("ignored an unexpected {} from the master", msg.type);
    }
  }

  /// Sleeps for the back-off (in short steps, so that a stop is seen) and connects again.
  void reconnect(const std::atomic<bool>& stop) {
    log()->warn("the master at {} is silent for {:.1f} s; reconnecting in {:.1f} s", options.master,
                seconds_since(last_heard), backoff.count() / 1000.0);
    socket.reset();
    welcomed = false;
    const auto until = Clock::now() + backoff;
    while (Clock::now() < until && !(stop.load() && !rendering)) {
      std::this_thread::sleep_for(milliseconds{20});
    }
    backoff = std::min(backoff * 2, options.heartbeat.reconnect_max);
    if (needs_bundle) needs_bundle.reset();  // the master takes the unit back when it loses us
    connect();
  }

  int run(const std::atomic<bool>& stop) {
    try {
      connect();
    } catch (const net::NetError& e) {
      log()->error("{}", e.what());
      return 1;
    }
    bool stop_logged = false;
    while (!refused) {
      if (stop.load() && !stop_logged) {
        stop_logged = true;
        log()->info(rendering ? "stopping after the unit in hand" : "stopping");
      }
      if (stop.load() && !rendering) break;

      auto wait = std::chrono::duration_cast<milliseconds>(next_heartbeat - Clock::now());
      wait = std::clamp(wait, milliseconds{0}, milliseconds{100});
      if (rendering) {
        // Wait on the unit itself, so that its result leaves the moment it is ready; what the
        // master sent meanwhile (heartbeats) is read right after.
        if (render.wait_for(wait) == std::future_status::ready) collect_render(stop.load());
        wait = milliseconds{0};
      }
      if (auto frames = socket->receive(wait)) {
        last_heard = Clock::now();
        handle(*frames, stop);
        while (!refused) {
          auto more = socket->receive(milliseconds{0});
          if (!more) break;
          handle(*more, stop);
        }
      }
      const auto now = Clock::now();
      if (now >= next_heartbeat) {
        send(encode(wire::Heartbeat{}));
        next_heartbeat = now + options.heartbeat.interval;
      }
      if (now - last_heard > options.heartbeat.expiry()) reconnect(stop);
    }
    if (rendering) render.wait();  // refused mid-unit: let the thread end before we do
    finish_job_log();
    if (socket && welcomed) {
      wire::Goodbye bye;
      bye.set_reason(refused ? "refused" : "stopped");
      send(encode(std::move(bye)));
      socket->set_linger(kFinalLinger);
    }
    socket.reset();
    log()->info("worker stopped after {} units", units_done.load());
    return refused ? 1 : 0;
  }
};

Agent::Agent(AgentOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}
Agent::~Agent() = default;

int Agent::run(const std::atomic<bool>& stop) { return impl_->run(stop); }

uint64_t Agent::units_rendered() const { return impl_->units_done.load(); }

}  // namespace rayfarm::worker
