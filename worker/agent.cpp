#include "worker/agent.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <system_error>
#include <thread>
#include <vector>

#include <tbb/task_arena.h>
#include <unistd.h>

#include "common/bundle/bundle.h"
#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/parser.h"
#include "common/util/log.h"
#include "common/util/log_throttle.h"
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
/// How often at most a worker logs that messages to the master are dropped: a refused worker's
/// heartbeats are dropped every interval for as long as it is refused.
constexpr std::chrono::seconds kDroppedLogInterval{60};

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

/// The scene and renderer of one job, identified by everything they depend on.
struct Prepared {
  std::string key;
  std::string job_id;
  std::unique_ptr<Scene> scene;  // outlives the renderer built from it
  std::unique_ptr<Renderer> renderer;
};

/// What this worker did for one job, for the line logged when it moves on.
struct JobStats {
  std::string job_id;
  uint64_t units = 0;
  uint64_t samples = 0;
  double seconds = 0.0;
};

/// What a render thread hands back: a result or the reason it failed.
struct Outcome {
  wire::UnitResult result;
  std::string error;
  bool ok = false;
};

std::string unit_key(const wire::WorkUnit& unit) {
  return unit.job_id() + '\0' + unit.bundle_hash() + '\0' + unit.scene_path() + '\0' +
         unit.settings().SerializeAsString() + '\0' + std::to_string(unit.film_width()) + 'x' +
         std::to_string(unit.film_height());
}

}  // namespace

std::string default_worker_name() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return std::string(host[0] ? host : "worker") + "-" + std::to_string(::getpid());
}

struct Agent::Impl {
  struct InFlight {
    uint64_t seq = 0;
    wire::WorkUnit unit;
  };

  AgentOptions options;
  tbb::task_arena arena;
  size_t capacity;  // units asked for or in hand at most

  // The reactor's state (this thread only).
  std::unique_ptr<net::Dealer> socket;
  bool welcomed = false;
  bool refused = false;
  bool stopping = false;
  Clock::time_point last_heard;
  Clock::time_point next_heartbeat;
  milliseconds backoff;
  size_t asked = 0;                          // WorkRequests not answered yet
  std::vector<wire::WorkUnit> needs_bundle;  // units waiting for their bundle
  std::string bundle_requested;              // the hash asked for, "" when none
  Clock::time_point bundle_retry{};          // the master said to ask again after this
  std::vector<InFlight> in_flight;
  uint64_t next_seq = 0;
  std::deque<net::Frames> outbox;  // results to send once welcomed again
  std::atomic<uint64_t> units_done{0};
  std::string reported_handshake;  // the handshake failure logged last
  LogThrottle dropped_log{kDroppedLogInterval};  // messages the socket would not take
  std::atomic<uint64_t> messages_dropped{0};

  // Shared with the render threads.
  std::mutex prepare_mutex;  // one job is prepared at a time
  std::mutex mutex;          // guards what follows
  std::condition_variable finished_cv;
  std::vector<std::pair<uint64_t, Outcome>> finished;  // outcomes by seq, not collected yet
  std::condition_variable work_cv;
  std::deque<InFlight> queue;  // units for the render threads
  bool shutting_down = false;
  std::vector<std::thread> render_threads;  // `capacity` of them, for the worker's lifetime
  std::shared_ptr<const Prepared> prepared;
  JobStats stats;

  explicit Impl(AgentOptions o)
      : options(std::move(o)),
        arena(options.threads == 0 ? tbb::task_arena::automatic
                                   : static_cast<int>(options.threads)),
        capacity(options.units_in_flight != 0 ? options.units_in_flight
                                              : (arena.max_concurrency() >= 2 ? 2 : 1)),
        backoff(options.heartbeat.reconnect_min) {
    if (options.name.empty()) options.name = default_worker_name();
    std::error_code ec;
    fs::create_directories(options.cache_dir, ec);
    if (ec) {
      throw std::runtime_error("cannot create cache dir " + options.cache_dir.string() + ": " +
                               ec.message());
    }
    for (size_t i = 0; i < capacity; ++i) render_threads.emplace_back([this] { render_loop(); });
  }

  ~Impl() {
    {
      std::lock_guard lock(mutex);
      shutting_down = true;
    }
    work_cv.notify_all();
    for (auto& t : render_threads) t.join();
  }

  /// A render thread: takes units from the queue and posts their outcomes until shut down.
  void render_loop() {
    std::unique_lock lock(mutex);
    while (true) {
      work_cv.wait(lock, [&] { return shutting_down || !queue.empty(); });
      if (shutting_down) return;
      InFlight job = std::move(queue.front());
      queue.pop_front();
      lock.unlock();
      Outcome outcome = render_unit(job.unit);
      lock.lock();
      finished.emplace_back(job.seq, std::move(outcome));
      finished_cv.notify_one();
    }
  }

  int threads() const { return arena.max_concurrency(); }

  void send(const net::Frames& frames) {
    if (!socket || socket->send(frames)) return;
    ++messages_dropped;
    const LogThrottle::Verdict verdict = dropped_log.occur();
    if (!verdict.log) return;
    if (welcomed) {
      log()->warn("send queue to the master is full; message dropped{}",
                  LogThrottle::suffix(verdict));
    } else {
      // No connection takes messages: the master refused this worker's key or security (or a
      // connection is being made again); check_handshake says which.
      log()->warn(
          "no connection to the master takes messages (it has not let this worker in); "
          "message dropped{}, logged at most every {} s",
          LogThrottle::suffix(verdict), kDroppedLogInterval.count());
    }
  }

  void connect() {
    socket =
        std::make_unique<net::Dealer>(options.master, net::kDefaultMaxMessageBytes, options.curve);
    last_heard = Clock::now();
    next_heartbeat = last_heard + options.heartbeat.interval;
    say_hello();
  }

  /// Starts over with the master: what was asked of the old one is forgotten; units in hand
  /// still return their results.
  void say_hello() {
    welcomed = false;
    asked = 0;
    needs_bundle.clear();
    bundle_requested.clear();
    wire::Hello hello;
    hello.set_role(wire::ROLE_WORKER);
    hello.set_name(options.name);
    hello.set_threads(static_cast<uint32_t>(threads()));
    hello.set_build(protocol::kBuildVersion);
    send(encode(std::move(hello)));
  }

  void request_work() {
    if (!welcomed || stopping || refused) return;
    while (asked + in_flight.size() + needs_bundle.size() < capacity) {
      send(encode(wire::WorkRequest{}));
      ++asked;
    }
  }

  void fail_unit(const wire::WorkUnit& unit, const std::string& reason) {
    log()->error("job {} unit {} failed: {}", unit.job_id(), unit.unit_id(), reason);
    wire::UnitFailed failed;
    failed.set_job_id(unit.job_id());
    failed.set_unit_id(unit.unit_id());
    failed.set_reason(reason);
    send(encode(std::move(failed)));
  }

  // --- Rendering (render threads) ---

  void log_job_stats() {  // mutex held
    if (stats.units == 0) return;
    log()->info("job {}: rendered {} units, {:.3g} samples in {:.2f} s", stats.job_id, stats.units,
                static_cast<double>(stats.samples), stats.seconds);
  }

  /// The scene and renderer for `unit`'s job, loaded on first use and kept while the job lasts.
  std::shared_ptr<const Prepared> prepare(const wire::WorkUnit& unit) {
    const std::string key = unit_key(unit);
    std::lock_guard prepare_lock(prepare_mutex);
    {
      std::lock_guard lock(mutex);
      if (prepared && prepared->key == key) return prepared;
    }
    const auto start = Clock::now();
    auto p = std::make_shared<Prepared>();
    p->key = key;
    p->job_id = unit.job_id();
    p->scene = std::make_unique<Scene>(
        load_scene(options.cache_dir / unit.bundle_hash() / unit.scene_path()));
    if (unit.film_width() != 0 && unit.film_height() != 0) {  // the job's film
      p->scene->film = {unit.film_width(), unit.film_height()};
    }
    const RenderSettings settings = protocol::settings_from_wire(unit.settings());
    arena.execute([&] { p->renderer = std::make_unique<Renderer>(*p->scene, settings); });
    log()->info(
        "job {}: {} {}x{}, {} spp, {}, seed {}; renderer ready in {:.2f} s ({} threads, {} units "
        "at once): {}",
        unit.job_id(), unit.scene_path(), p->scene->film.width, p->scene->film.height, settings.spp,
        integrator_name(settings.integrator), settings.seed, seconds_since(start), threads(),
        capacity, p->renderer->plan());
    std::lock_guard lock(mutex);
    if (stats.job_id != p->job_id) {
      log_job_stats();
      stats = JobStats{p->job_id};
    }
    prepared = p;
    return p;
  }

  Outcome render_unit(const wire::WorkUnit& unit) {
    Outcome out;
    try {
      const std::shared_ptr<const Prepared> p = prepare(unit);
      const TileRect rect = protocol::rect_from_wire(unit.tile());
      if (unit.sample_end() <= unit.sample_begin()) {
        throw protocol::ProtocolError("empty sample range");
      }
      const SampleRange samples{unit.sample_begin(), unit.sample_end()};
      const auto start = Clock::now();
      TileResult result;
      arena.execute([&] { result = p->renderer->render(rect, samples); });
      const double seconds = seconds_since(start);
      {
        std::lock_guard lock(mutex);
        if (stats.job_id == unit.job_id()) {
          ++stats.units;
          stats.samples += uint64_t{rect.pixel_count()} * samples.count();
          stats.seconds += seconds;
        }
      }
      log()->debug("job {} unit {} (pass {}): tile [{},{})x[{},{}) samples [{},{}) in {:.3f} s",
                   unit.job_id(), unit.unit_id(), unit.pass(), rect.x0, rect.x1, rect.y0, rect.y1,
                   samples.begin, samples.end, seconds);
      out.result = protocol::result_to_wire(unit.job_id(), unit.unit_id(), result, seconds);
      out.ok = true;
    } catch (const std::exception& e) {
      out.error = e.what();
    }
    return out;
  }

  // --- The reactor (this thread) ---

  void launch(const wire::WorkUnit& unit) {
    const uint64_t seq = next_seq++;
    in_flight.push_back({seq, unit});
    {
      std::lock_guard lock(mutex);
      queue.push_back({seq, unit});
    }
    work_cv.notify_one();
  }

  void start_unit(const wire::WorkUnit& unit) {
    if (!is_bundle_hash(unit.bundle_hash())) {
      fail_unit(unit, "bad bundle hash '" + unit.bundle_hash() + "'");
      request_work();
      return;
    }
    std::error_code ec;
    if (fs::is_directory(options.cache_dir / unit.bundle_hash(), ec)) {
      launch(unit);
      return;
    }
    needs_bundle.push_back(unit);
    request_bundle();
  }

  /// Asks for the bundle of the first unit waiting for one, unless a request is out.
  void request_bundle() {
    if (!bundle_requested.empty() || needs_bundle.empty() || Clock::now() < bundle_retry) return;
    const wire::WorkUnit& unit = needs_bundle.front();
    log()->info("job {}: fetching bundle {} from the master", unit.job_id(),
                unit.bundle_hash().substr(0, 12));
    bundle_requested = unit.bundle_hash();
    wire::BundleRequest request;
    request.set_hash(bundle_requested);
    send(encode(std::move(request)));
  }

  void on_bundle(const wire::BundleReply& reply) {
    if (reply.hash() != bundle_requested) {
      log()->debug("ignored an unrequested bundle {}", reply.hash().substr(0, 12));
      return;
    }
    bundle_requested.clear();
    if (reply.retry_after_ms() > 0) {
      // Not refused: the master sends it later. The units keep waiting; wait_and_handle() asks
      // again once the time has passed.
      log()->info("the master will send bundle {} later: {}", reply.hash().substr(0, 12),
                  reply.error());
      bundle_retry = Clock::now() + milliseconds{std::min<uint32_t>(reply.retry_after_ms(), 60000)};
      return;
    }
    std::vector<wire::WorkUnit> ready;
    auto waiting = std::stable_partition(
        needs_bundle.begin(), needs_bundle.end(),
        [&](const wire::WorkUnit& u) { return u.bundle_hash() != reply.hash(); });
    ready.assign(std::make_move_iterator(waiting), std::make_move_iterator(needs_bundle.end()));
    needs_bundle.erase(waiting, needs_bundle.end());

    std::string error = reply.error();
    if (error.empty()) {
      try {
        const Bundle bundle = protocol::bundle_from_wire(reply.bundle());
        const fs::path dir = unpack_bundle(bundle, options.cache_dir, reply.hash());
        log()->info("bundle {} cached in {} ({} files)", reply.hash().substr(0, 12), dir.string(),
                    bundle.files.size());
      } catch (const std::exception& e) {
        error = std::string("cannot unpack the bundle: ") + e.what();
      }
    }
    for (const auto& unit : ready) {
      if (error.empty()) {
        launch(unit);
      } else {
        fail_unit(unit, error);
      }
    }
    request_bundle();
    request_work();
  }

  /// Sends the results of every finished render and asks for more work.
  void collect_finished() {
    std::vector<std::pair<uint64_t, Outcome>> outcomes;
    {
      std::lock_guard lock(mutex);
      outcomes.swap(finished);
    }
    for (auto& [seq, outcome] : outcomes) {
      auto it = std::find_if(in_flight.begin(), in_flight.end(),
                             [seq = seq](const InFlight& f) { return f.seq == seq; });
      const wire::WorkUnit unit = std::move(it->unit);
      in_flight.erase(it);
      if (outcome.ok) {
        ++units_done;
        net::Frames frames = encode(std::move(outcome.result));
        if (welcomed) {
          send(frames);
        } else {
          outbox.push_back(std::move(frames));  // sent after the next Welcome
        }
      } else {
        fail_unit(unit, outcome.error);
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
      for (const auto& frames_out : outbox) send(frames_out);
      outbox.clear();
      request_work();
    } else if (msg.as<wire::Heartbeat>()) {
      // liveness only
    } else if (const auto* unit = msg.as<wire::WorkUnit>()) {
      if (asked > 0) --asked;
      if (in_flight.size() + needs_bundle.size() >= capacity) {
        log()->warn("the master sent job {} unit {} beyond the {} units this worker takes at once",
                    unit->job_id(), unit->unit_id(), capacity);
        fail_unit(*unit, "the worker has no room for another unit");
        return;
      }
      start_unit(*unit);
    } else if (const auto* reply = msg.as<wire::BundleReply>()) {
      on_bundle(*reply);
    } else if (const auto* error = msg.as<wire::Error>()) {
      log()->warn("the master says: {}", error->message());
      if (error->code() == wire::Error::UNKNOWN_WORKER && welcomed) {
        // The master restarted (or declared us lost) and the connection came back by itself.
        say_hello();
      }
    } else {
      log()->warn("ignored an unexpected {} from the master", msg.type);
    }
  }

  /// Logs a failed security handshake once per cause (the socket keeps retrying by itself, so a
  /// key added to the master's allow-list later lets the worker in).
  void check_handshake() {
    const net::HandshakeStatus st = socket->handshake();
    if (st.state == net::Handshake::kSucceeded) reported_handshake.clear();
    if (st.state == net::Handshake::kSucceeded || st.state == net::Handshake::kPending) return;
    if (st.detail == reported_handshake) return;
    reported_handshake = st.detail;
    log()->error("the master at {} did not let this worker in: {}{}; retrying", options.master,
                 st.detail,
                 st.state == net::Handshake::kRefused
                     ? " (add this worker's public key to the master's --worker-keys)"
                     : "");
  }

  /// Sleeps for the back-off (in short steps, so that a stop is seen) and connects again.
  void reconnect(const std::atomic<bool>& stop) {
    log()->warn("the master at {} is silent for {:.1f} s; reconnecting in {:.1f} s", options.master,
                seconds_since(last_heard), backoff.count() / 1000.0);
    socket.reset();
    welcomed = false;
    const auto until = Clock::now() + backoff;
    while (Clock::now() < until && !(stop.load() && in_flight.empty())) {
      std::this_thread::sleep_for(milliseconds{20});
    }
    backoff = std::min(backoff * 2, options.heartbeat.reconnect_max);
    connect();
  }

  /// Waits up to `wait` for a render to finish or a message to arrive, and handles what came.
  void wait_and_handle(milliseconds wait) {
    if (!needs_bundle.empty() && bundle_requested.empty()) {
      request_bundle();  // a bundle the master said to ask for again later
      wait = std::min(wait, milliseconds{100});
    }
    if (!in_flight.empty()) {
      // Wait on the renders themselves, so that a result leaves the moment it is ready; what the
      // master sent meanwhile (heartbeats) is read right after.
      {
        std::unique_lock lock(mutex);
        finished_cv.wait_for(lock, wait, [&] { return !finished.empty(); });
      }
      collect_finished();
      wait = milliseconds{0};
    }
    if (auto frames = socket->receive(wait)) {
      last_heard = Clock::now();
      handle(*frames);
      while (!refused) {
        auto more = socket->receive(milliseconds{0});
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
      connect();
    } catch (const net::NetError& e) {
      log()->error("{}", e.what());
      return 1;
    }
    Clock::time_point stop_deadline;
    bool abandoned = false;
    while (!refused) {
      if (stop.load() && !stopping) {
        stopping = true;
        stop_deadline = Clock::now() + options.stop_grace;
        if (in_flight.empty()) {
          log()->info("stopping");
        } else {
          log()->info("stopping after the {} unit{} in hand", in_flight.size(),
                      in_flight.size() == 1 ? "" : "s");
        }
      }
      if (stopping && in_flight.empty()) break;
      if (stopping && Clock::now() >= stop_deadline) {
        log()->warn(
            "the {} unit{} in hand did not finish within {:g} s of the stop; the master "
            "takes {} back",
            in_flight.size(), in_flight.size() == 1 ? "" : "s",
            static_cast<double>(options.stop_grace.count()) / 1000.0,
            in_flight.size() == 1 ? "it" : "them");
        abandoned = true;
        break;
      }

      auto wait = std::chrono::duration_cast<milliseconds>(next_heartbeat - Clock::now());
      wait_and_handle(std::clamp(wait, milliseconds{0}, milliseconds{100}));
      const auto now = Clock::now();
      if (now >= next_heartbeat) {
        send(encode(wire::Heartbeat{}));
        next_heartbeat = now + options.heartbeat.interval;
      }
      if (!welcomed) check_handshake();
      if (now - last_heard > options.heartbeat.expiry()) reconnect(stop);
    }
    // Refused mid-unit: let the renders end before the worker does.
    while (!in_flight.empty() && !abandoned) {
      {
        std::unique_lock lock(mutex);
        finished_cv.wait(lock, [&] { return !finished.empty(); });
      }
      collect_finished();
    }
    {
      std::lock_guard lock(mutex);
      log_job_stats();
    }
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

uint64_t Agent::messages_dropped() const { return impl_->messages_dropped.load(); }

}  // namespace rayfarm::worker
