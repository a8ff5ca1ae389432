#include "master/broker.h"

#include <algorithm>
#include <array>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>
#include <tuple>
#include <vector>

#include "common/net/zap.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/util/log.h"

namespace rayfarm::master {
namespace protocol = rayfarm::protocol;
using protocol::encode;
using std::chrono::milliseconds;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("master"); }

/// Most messages handled from one socket before the timers and the other socket get a turn.
constexpr int kBatch = 256;
/// Most WorkRequests a worker may have outstanding (a worker renders a few units at once).
constexpr uint32_t kMaxWants = 4;

net::Frames error_frames(const std::string& message, const std::string& job_id = "") {
  wire::Error e;
  e.set_message(message);
  e.set_job_id(job_id);
  return encode(std::move(e));
}

net::Frames refusal_frames(uint32_t peer_version, const char* peer_kind) {
  wire::Refusal r;
  r.set_master_version(protocol::kProtocolVersion);
  r.set_peer_version(peer_version);
  r.set_reason(
      fmt::format("protocol version mismatch: the master speaks version {}, the {} sent "
                  "version {}",
                  protocol::kProtocolVersion, peer_kind, peer_version));
  return encode(std::move(r));
}

/// A job another key may not see: said as if it were unknown, so that it does not leak.
std::string not_visible(const std::string& id) {
  return "unknown job '" + protocol::printable(id) +
         "' (this master keeps jobs private to the key that submitted them)";
}

std::string not_owner(const std::string& id, const std::string& owner, const char* action) {
  return fmt::format(
      "job {} belongs to key '{}': only that key or an admin key (rayfarm-master "
      "--admin-clients) may {} it",
      protocol::printable(id), protocol::printable(owner), action);
}

/// What one connection can make the master queue (docs/reliability.md): messages per peer in each
/// direction on each socket. A client sends one request and reads its reply; a worker has at most
/// kMaxWants units, a few results and heartbeats in flight.
constexpr net::QueueBounds kWorkerQueues{/*send=*/64, /*receive=*/16};
constexpr net::QueueBounds kClientQueues{/*send=*/8, /*receive=*/4};
/// A worker connection gets one bundle at most once per window, and bundles of at most twice the
/// bundle limit in all per window.
constexpr auto kBundleWindow = std::chrono::seconds{60};

/// Submissions waiting to be checked (or being checked), in all and from one connection; more are
/// refused as busy (the CLI tries again).
constexpr size_t kMaxSubmissionsInFlight = 16;
constexpr size_t kMaxSubmissionsPerPeer = 1;
constexpr size_t kMaxSubmissionsPerKey = 4;

/// Repeated refusals of the same key from the same address are logged at most this often.
constexpr auto kRefusalLogInterval = std::chrono::seconds{10};

net::Curve curve_for(const MasterOptions& options, const char* domain) {
  net::Curve curve;
  if (options.security.key) {
    curve.public_key = options.security.key->public_key;
    curve.secret_key = options.security.key->secret_key;
    curve.zap_domain = domain;
  }
  return curve;
}

}  // namespace

/// The ZAP handler and the allow-lists it admits keys from; it logs every refusal with the
/// peer's address (repeats of the same refusal at most every kRefusalLogInterval).
struct Broker::Gate {
  net::AllowListPolicy policy;
  std::mutex mutex;  // guards `recent` (the ZAP thread only, but cheap to be sure)
  std::map<std::tuple<std::string, std::string, std::string>, LogThrottle> recent;
  net::ZapHandler handler;

  explicit Gate(const MasterSecurity& security)
      : policy({{kWorkerDomain, security.worker_keys}, {kClientDomain, security.client_keys}}),
        handler([this](const net::ZapRequest& r) { return decide(r); }) {}

  net::ZapVerdict decide(const net::ZapRequest& r) {
    const net::AllowListPolicy::Decision d = policy.decide(r);
    if (!d.reload_note.empty()) {
      log()->log(d.reload_warning ? spdlog::level::warn : spdlog::level::info, "{}", d.reload_note);
    }
    if (d.admitted) return {true, d.name};
    const char* role = r.domain == kWorkerDomain ? "worker" : "client";
    std::lock_guard lock(mutex);
    if (recent.size() > 4096) recent.clear();
    const LogThrottle::Verdict verdict =
        recent.try_emplace({r.domain, r.address, r.key}, kRefusalLogInterval).first->second.occur();
    if (verdict.log) {
      log()->warn("refused a {} connection from {}: {}{}", role, r.address, d.reason,
                  LogThrottle::suffix(verdict));
    }
    return {};
  }
};

/// Checks submissions against the limits, unpacks their bundles, loads their scenes, reads their
/// references and stores them (JobManager::prepare), on a thread of its own: the reactor keeps
/// serving heartbeats and results meanwhile, and admits each job once it is ready.
class Broker::Submissions {
 public:
  struct Done {
    net::PeerId peer;
    std::string label;  // the client, for the log
    std::string scene;  // the scene path, printable, for the log
    std::optional<JobManager::PreparedJob> job;
    std::string error;  // why it was refused
    std::string user;   // the client's key
    uint64_t bytes = 0;
  };

  Submissions(const JobManager& jobs, Limits limits)
      : jobs_(jobs), limits_(std::move(limits)), thread_([this] { loop(); }) {}
  ~Submissions() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }

  /// Queues a submission of `bytes` (its bundle's); false when too many are waiting: in all, from
  /// `peer` or from its key `user`, or in bytes (twice the bundle limit, one always fits).
  bool add(const net::PeerId& peer, std::string label, std::string user, wire::SubmitJob job,
           uint64_t bytes) {
    std::lock_guard lock(mutex_);
    const size_t from_peer = per_peer_.count(peer) ? per_peer_.at(peer) : 0;
    const size_t from_key = per_key_.count(user) ? per_key_.at(user) : 0;
    if (in_flight_ >= kMaxSubmissionsInFlight || from_peer >= kMaxSubmissionsPerPeer ||
        from_key >= kMaxSubmissionsPerKey ||
        (in_flight_ > 0 && bytes_ + bytes > 2 * limits_.max_bundle_bytes)) {
      return false;
    }
    ++in_flight_;
    ++per_peer_[peer];
    ++per_key_[user];
    bytes_ += bytes;
    queue_.push_back(Task{peer, std::move(label), std::move(user), std::move(job), bytes});
    wake_.notify_one();
    return true;
  }
  /// The submissions checked since the last call.
  std::vector<Done> take_done() {
    std::lock_guard lock(mutex_);
    std::vector<Done> out;
    out.swap(done_);
    for (const Done& d : out) {
      --in_flight_;
      bytes_ -= d.bytes;
      if (--per_peer_[d.peer] == 0) per_peer_.erase(d.peer);
      if (--per_key_[d.user] == 0) per_key_.erase(d.user);
    }
    return out;
  }
  /// Submissions queued or being checked.
  size_t in_flight() const {
    std::lock_guard lock(mutex_);
    return in_flight_;
  }
  /// Waits until every queued submission is checked.
  void drain() {
    std::unique_lock lock(mutex_);
    idle_.wait(lock, [this] { return queue_.empty() && !busy_; });
  }

 private:
  struct Task {
    net::PeerId peer;
    std::string label;
    std::string user;
    wire::SubmitJob job;
    uint64_t bytes = 0;
  };
  const JobManager& jobs_;
  const Limits limits_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, idle_;
  std::deque<Task> queue_;
  std::vector<Done> done_;
  std::map<net::PeerId, size_t> per_peer_;
  std::map<std::string, size_t> per_key_;
  size_t in_flight_ = 0;
  uint64_t bytes_ = 0;
  bool busy_ = false;
  bool stop_ = false;
  std::thread thread_;  // last: starts once the rest is ready

  void loop() {
    std::unique_lock lock(mutex_);
    for (;;) {
      wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, nothing left
      Task task = std::move(queue_.front());
      queue_.pop_front();
      busy_ = true;
      lock.unlock();
      Done done{task.peer,
                std::move(task.label),
                protocol::printable(task.job.scene_path(), 200),
                std::nullopt,
                "",
                task.user,
                task.bytes};
      try {
        // The scene parser checks the limits before it loads any mesh.
        done.job = jobs_.prepare(task.job, task.user, scene_check(task.job, limits_));
      } catch (const JobRejected& e) {
        done.error = e.what();
      } catch (const std::exception& e) {
        done.error = std::string("the master failed to check the job: ") + e.what();
      }
      lock.lock();
      done_.push_back(std::move(done));
      busy_ = false;
      idle_.notify_all();
    }
  }
};

std::unique_ptr<Broker::Gate> Broker::open_gate(const MasterOptions& options) {
  if (!options.security.key) {
    for (const std::string& endpoint : {options.worker_endpoint, options.client_endpoint}) {
      if (!net::is_loopback_endpoint(endpoint)) {
        throw std::runtime_error(
            "--insecure is allowed only on loopback endpoints, and " + endpoint +
            " is reachable from other machines: bind 127.0.0.1, or give the master its key and "
            "allow-lists (--key, --worker-keys, --client-keys; see docs/deploy.md)");
      }
    }
    log()->warn(
        "INSECURE: no authentication and no encryption on {} and {}; any local process can "
        "submit jobs or pose as a worker. Use keys (rayfarm keygen) for anything but a quick try",
        options.worker_endpoint, options.client_endpoint);
    return nullptr;
  }
  net::require_curve();
  if (options.security.worker_keys.empty() || options.security.client_keys.empty()) {
    throw net::KeyError(
        "the master needs an allow-list of worker keys (--worker-keys) and one of client keys "
        "(--client-keys): files or folders of public keys made by rayfarm keygen");
  }
  try {
    auto gate = std::make_unique<Gate>(options.security);
    log()->info("CURVE on both sockets, master key {}: {} worker key{} ({}), {} client key{} ({})",
                net::key_label(options.security.key->public_key), gate->policy.size(kWorkerDomain),
                gate->policy.size(kWorkerDomain) == 1 ? "" : "s",
                options.security.worker_keys.string(), gate->policy.size(kClientDomain),
                gate->policy.size(kClientDomain) == 1 ? "" : "s",
                options.security.client_keys.string());
    return gate;
  } catch (const net::NetError& e) {
    throw net::NetError(std::string("the master cannot authenticate its peers: ") + e.what());
  }
}

Broker::Broker(MasterOptions options)
    : options_(std::move(options)),
      store_(options_.data_dir),
      jobs_(store_,
            [this] {
              JobManagerOptions o = options_.jobs;
              o.image_interval = options_.image_interval;
              o.worker_name = [this](const WorkerId& w) { return worker_label(w); };
              o.connected_workers = [this] {
                std::vector<std::string> out;
                for (const auto& [peer, w] : workers_)
                  out.push_back(w.key_name.empty() ? peer : w.key_name);
                return out;
              };
              return o;
            }()),
      gate_(open_gate(options_)),
      workers_socket_(options_.worker_endpoint, options_.limits.max_message_bytes,
                      curve_for(options_, kWorkerDomain), kWorkerQueues),
      clients_socket_(options_.client_endpoint, options_.limits.max_message_bytes,
                      curve_for(options_, kClientDomain), kClientQueues),
      next_heartbeat_(Clock::now()) {
  submissions_ = std::make_unique<Submissions>(jobs_, options_.limits);
  const size_t restarted = jobs_.recover();
  log()->info("master listening: workers on {}, clients on {}; data dir {}{}", worker_endpoint(),
              client_endpoint(), options_.data_dir.string(),
              restarted ? fmt::format(" ({} unfinished jobs restarted)", restarted) : "");
  log()->info("heartbeat every {} ms, a worker is lost after {} ms of silence",
              options_.heartbeat.interval.count(), options_.heartbeat.expiry().count());
}

Broker::~Broker() = default;

std::string Broker::worker_label(const net::PeerId& peer) const {
  const std::string id = net::peer_label(peer);
  auto it = workers_.find(peer);
  if (it == workers_.end()) return "worker " + id;
  return fmt::format("worker {} ({})", it->second.name, id);
}

void Broker::run(const std::atomic<bool>& stop) {
  std::array<net::Socket*, 2> sockets{&workers_socket_, &clients_socket_};
  while (!stop.load()) {
    const auto until_heartbeat =
        std::chrono::duration_cast<milliseconds>(next_heartbeat_ - Clock::now());
    const auto wait = std::clamp(until_heartbeat, milliseconds{0}, milliseconds{100});
    const auto readable = net::poll(sockets, wait);
    listened_ = Clock::now();
    if (readable[0]) {
      for (int i = 0; i < kBatch; ++i) {
        auto delivery = workers_socket_.receive(milliseconds{0});
        if (!delivery) break;
        handle_worker(*delivery);
      }
    }
    if (readable[1]) {
      for (int i = 0; i < kBatch; ++i) {
        auto delivery = clients_socket_.receive(milliseconds{0});
        if (!delivery) break;
        handle_client(*delivery);
      }
    }
    admit_submissions();
    on_timers();
  }
  // Submissions being checked are finished and answered: each is on disk once checked.
  submissions_->drain();
  admit_submissions();
  jobs_.shutdown();  // every running job checkpointed before the master exits
  log()->info("master stopping: {} workers connected, {} jobs unfinished (kept in {})",
              workers_.size(), jobs_.active_jobs(), options_.data_dir.string());
}

void Broker::on_timers() {
  const auto now = Clock::now();
  if (now >= next_heartbeat_) {
    const net::Frames beat = encode(wire::Heartbeat{});
    for (const auto& [peer, w] : workers_) workers_socket_.send(peer, beat);
    next_heartbeat_ = now + options_.heartbeat.interval;
  }
  // Messages that arrived while the master was busy since it last polled (the end of a pass of a
  // large image) are still unread: that time does not count as the workers' silence, up to one
  // more liveness window per worker, so that a worker that truly went silent is still found.
  const auto deaf = now - listened_;
  if (deaf > options_.heartbeat.interval) {
    for (auto& [peer, w] : workers_) {
      const auto credit = std::min<Clock::duration>(deaf, options_.heartbeat.expiry() - w.forgiven);
      if (credit <= Clock::duration::zero()) continue;
      w.expires += credit;
      w.forgiven += credit;
    }
  }
  std::vector<net::PeerId> expired;
  for (const auto& [peer, w] : workers_) {
    if (now > w.expires) expired.push_back(peer);
  }
  for (const auto& peer : expired) {
    const double silent = std::chrono::duration<double>(now - workers_[peer].heard).count();
    remove_worker(peer, fmt::format("lost: silent for {:.1f} s", silent));
  }
  jobs_.tick();
  if (jobs_.has_pending()) dispatch();  // stragglers become due with time alone
}

void Broker::heard_from(Worker& w) {
  w.heard = Clock::now();
  w.expires = w.heard + options_.heartbeat.expiry();
  w.forgiven = Clock::duration::zero();
}

void Broker::send_worker(const net::PeerId& peer, const net::Frames& frames) {
  if (!workers_socket_.send(peer, frames)) {
    log()->debug("cannot send to {}: disconnected or queue full", worker_label(peer));
  }
}

void Broker::reply(const net::PeerId& peer, const net::Frames& frames) {
  if (!clients_socket_.send(peer, frames)) {
    log()->debug("cannot reply to client {}: disconnected", net::peer_label(peer));
  }
}

void Broker::register_worker(const net::PeerId& peer, const wire::Hello& hello,
                             const std::string& key_name) {
  if (hello.role() != wire::ROLE_WORKER) {
    log()->warn("worker socket: {} said hello as a client; refused", net::peer_label(peer));
    send_worker(
        peer, error_frames("this is the worker endpoint; clients connect to the client endpoint"));
    return;
  }
  if (workers_.count(peer)) {
    jobs_.release_worker(peer);  // a worker that starts over holds nothing any more
  }
  Worker& w = workers_[peer];
  w.name = hello.name().empty() ? "unnamed" : protocol::printable(hello.name());
  w.threads = hello.threads();
  w.key_name = key_name;  // as the ZAP handler named it: leases and failures go by it
  w.build = protocol::printable(hello.build());
  heard_from(w);
  w.wants = 0;
  log()->info("{} joined{}: {} threads, {}; {} worker{} connected", worker_label(peer),
              key_name.empty() ? "" : " with key '" + protocol::printable(key_name) + "'",
              w.threads,
              hello.build().empty() ? "unknown build" : protocol::printable(hello.build()),
              workers_.size(), workers_.size() == 1 ? "" : "s");
  wire::Welcome welcome;
  welcome.set_build(protocol::kBuildVersion);
  welcome.set_heartbeat_interval_ms(static_cast<uint32_t>(options_.heartbeat.interval.count()));
  welcome.set_liveness(static_cast<uint32_t>(options_.heartbeat.liveness));
  send_worker(peer, encode(std::move(welcome)));
}

void Broker::remove_worker(const net::PeerId& peer, const std::string& why) {
  auto it = workers_.find(peer);
  if (it == workers_.end()) return;
  const std::string label = worker_label(peer);
  const size_t requeued = jobs_.release_worker(peer);
  workers_.erase(it);
  const auto level = why.rfind("lost", 0) == 0 ? spdlog::level::warn : spdlog::level::info;
  log()->log(level, "{} {}; {} unit{} requeued; {} worker{} connected", label, why, requeued,
             requeued == 1 ? "" : "s", workers_.size(), workers_.size() == 1 ? "" : "s");
  if (requeued) dispatch();
}

void Broker::dispatch() {
  // One unit per asking worker per round, so that scarce units spread over the workers.
  std::vector<net::PeerId> unreachable;
  bool sent = true;
  while (sent && jobs_.has_pending()) {
    sent = false;
    for (auto& [peer, w] : workers_) {
      if (w.wants == 0) continue;
      auto unit = jobs_.next_unit(peer, w.key_name);
      if (!unit) continue;  // e.g. blocked from the jobs that have units
      if (!workers_socket_.send(peer, encode(std::move(*unit)))) {
        unreachable.push_back(peer);
        w.wants = 0;
        continue;
      }
      --w.wants;
      ++w.units_sent;
      sent = true;
    }
  }
  for (const auto& peer : unreachable) remove_worker(peer, "unreachable (disconnected)");
}

void Broker::handle_worker(const net::Delivery& delivery) {
  const net::PeerId& peer = delivery.peer;
  protocol::Decoded msg;
  try {
    msg = protocol::decode(delivery.frames);
  } catch (const protocol::DecodeError& e) {
    complain("worker", delivery.user,
             fmt::format("ignored a bad message from {}: {}", worker_label(peer), e.what()));
    return;
  }
  if (!msg.version_ok()) {
    complain("worker", delivery.user,
             fmt::format("refused {} ({}): it speaks protocol version {}, this master {}",
                         worker_label(peer), msg.type, msg.version, protocol::kProtocolVersion));
    send_worker(peer, refusal_frames(msg.version, "worker"));
    remove_worker(peer, "refused (protocol version)");
    return;
  }
  try {
    if (const auto* hello = msg.as<wire::Hello>()) {
      register_worker(peer, *hello, delivery.user);
      return;
    }
    auto it = workers_.find(peer);
    if (it != workers_.end()) heard_from(it->second);

    if (const auto* result = msg.as<wire::UnitResult>()) {
      // Merged only when this connection was leased the unit; it may have been declared lost
      // since (its late result still counts: the bits do not depend on who rendered the unit,
      // and the merger takes each unit once).
      const MergeOutcome outcome = jobs_.on_result(peer, *result, delivery.user);
      if (outcome == MergeOutcome::kUnleased) {
        complain("worker", delivery.user,
                 fmt::format("dropped a result for job {} unit {} from {}: no such job, or the "
                             "unit was never leased to it",
                             protocol::printable(result->job_id()), result->unit_id(),
                             worker_label(peer)));
      }
      if (it != workers_.end() && outcome == MergeOutcome::kMerged) {
        Worker& w = it->second;
        const auto& t = result->tile();
        const auto now = Clock::now();
        if (w.units_merged++ == 0) {
          const double render = std::clamp(result->render_seconds(), 0.0, 3600.0);
          w.working_since = now - std::chrono::duration_cast<Clock::duration>(
                                      std::chrono::duration<double>(render));
        }
        w.last_result = now;
        w.samples_merged += double(t.x1() - t.x0()) * double(t.y1() - t.y0()) *
                            double(result->sample_end() - result->sample_begin());
      }
      if (it == workers_.end()) {
        send_worker(peer, error_frames("unknown worker: send Hello first"));
      }
      dispatch();
      return;
    }
    if (it == workers_.end()) {
      if (msg.as<wire::Goodbye>()) return;
      log()->debug("worker socket: {} from unknown {}; asking it to say hello", msg.type,
                   net::peer_label(peer));
      send_worker(peer, error_frames("unknown worker: send Hello first"));
      return;
    }
    Worker& w = it->second;
    if (msg.as<wire::Heartbeat>()) return;
    if (msg.as<wire::WorkRequest>()) {
      w.wants = std::min(w.wants + 1, kMaxWants);
      dispatch();
    } else if (const auto* failed = msg.as<wire::UnitFailed>()) {
      if (!jobs_.on_unit_failed(peer, *failed, delivery.user)) {
        complain("worker", delivery.user,
                 fmt::format("ignored a failure report for job {} unit {} from {}: the unit is "
                             "not leased to it, or its job is over",
                             protocol::printable(failed->job_id()), failed->unit_id(),
                             worker_label(peer)));
      }
      dispatch();
    } else if (const auto* request = msg.as<wire::BundleRequest>()) {
      send_bundle(peer, w, request->hash());
    } else if (const auto* bye = msg.as<wire::Goodbye>()) {
      remove_worker(
          peer, "left" + (bye->reason().empty() ? std::string()
                                                : " (" + protocol::printable(bye->reason()) + ")"));
    } else {
      complain("worker", delivery.user,
               fmt::format("unexpected {} from {}; ignored", msg.type, worker_label(peer)));
      send_worker(peer, error_frames("unexpected message " + msg.type + " on the worker endpoint"));
    }
  } catch (const std::exception& e) {
    log()->error("worker socket: failed to handle {} from {}: {}", msg.type, worker_label(peer),
                 e.what());
  }
}

void Broker::admit_submissions() {
  bool admitted = false;
  for (Submissions::Done& done : submissions_->take_done()) {
    wire::SubmitReply out;
    if (done.job) {
      try {
        out.set_job_id(jobs_.admit(std::move(*done.job)));
        admitted = true;
      } catch (const std::exception& e) {
        log()->error("job refused ({}) from {}: {}", done.scene, done.label, e.what());
        out.set_error(jobs_.for_clients(e.what()));
      }
    } else {
      log()->log(refusal_log_.take(done.user) ? spdlog::level::warn : spdlog::level::debug,
                 "job refused ({}) from {}: {}", done.scene, done.label, done.error);
      out.set_error(jobs_.for_clients(done.error));
    }
    reply(done.peer, encode(std::move(out)));
  }
  if (admitted) dispatch();
}

bool Broker::may_manage(const std::string& owner, const std::string& user) const {
  return owner == user || options_.security.admin_clients.count(user) != 0;
}

bool Broker::may_see(const std::string& owner, const std::string& user) const {
  return !options_.security.private_jobs || may_manage(owner, user);
}

void Broker::complain(const std::string& socket, const std::string& key, const std::string& text) {
  if (complaints_.size() > 4096) complaints_.clear();
  const LogThrottle::Verdict verdict =
      complaints_.try_emplace(socket + '\0' + key, kRefusalLogInterval).first->second.occur();
  if (verdict.log) log()->warn("{} socket: {}{}", socket, text, LogThrottle::suffix(verdict));
}

void Broker::send_bundle(const net::PeerId& peer, Worker& w, const std::string& hash) {
  wire::BundleReply reply_msg;
  reply_msg.set_hash(protocol::printable(hash, 80));
  const auto now = Clock::now();
  if (now - w.bundle_window >= kBundleWindow) {
    w.bundle_window = now;
    w.bundle_bytes = 0;
    w.bundles_sent.clear();
  }
  auto bundle = jobs_.bundle(hash);
  if (!bundle) {
    reply_msg.set_error("the master has no bundle " + protocol::printable(hash, 80));
    send_worker(peer, encode(std::move(reply_msg)));
    return;
  }
  // A worker keeps the bundles it fetched: asking again at once, or for more than the window
  // allows, is refused rather than queued (the replies would sit in the master's memory for as
  // long as the peer does not read them).
  const uint64_t bytes = bundle->ByteSizeLong();
  const char* refusal = nullptr;
  if (w.bundles_sent.count(hash)) {
    refusal = "it was sent to this connection less than a minute ago";
  } else if (w.bundle_bytes + bytes > 2 * options_.limits.max_bundle_bytes) {
    refusal =
        "this connection was sent more bundle bytes in the last minute than the master allows";
  }
  if (refusal) {
    log()->warn("bundle {} not sent to {}: {}", hash.substr(0, 12), worker_label(peer), refusal);
    reply_msg.set_error(std::string("the master will not send bundle ") + hash.substr(0, 12) +
                        " now: " + refusal + "; ask again later");
    const auto retry = std::chrono::duration_cast<std::chrono::milliseconds>(w.bundle_window +
                                                                             kBundleWindow - now);
    reply_msg.set_retry_after_ms(static_cast<uint32_t>(std::max<int64_t>(retry.count(), 1000)));
    send_worker(peer, encode(std::move(reply_msg)));
    return;
  }
  w.bundles_sent.insert(hash);
  w.bundle_bytes += bytes;
  *reply_msg.mutable_bundle() = std::move(*bundle);
  log()->debug("bundle {} sent to {}", hash.substr(0, 12), worker_label(peer));
  send_worker(peer, encode(std::move(reply_msg)));
}

void Broker::handle_client(const net::Delivery& delivery) {
  const net::PeerId& peer = delivery.peer;
  const std::string label =
      "client " + net::peer_label(peer) +
      (delivery.user.empty() ? "" : " (key '" + protocol::printable(delivery.user) + "')");
  protocol::Decoded msg;
  try {
    msg = protocol::decode(delivery.frames);
  } catch (const protocol::DecodeError& e) {
    complain("client", delivery.user,
             fmt::format("ignored a bad message from {}: {}", label, e.what()));
    reply(peer, error_frames(std::string("cannot decode the request: ") + e.what()));
    return;
  }
  if (!msg.version_ok()) {
    complain("client", delivery.user,
             fmt::format("refused {} ({}): it speaks protocol version {}, this master {}", label,
                         msg.type, msg.version, protocol::kProtocolVersion));
    reply(peer, refusal_frames(msg.version, "client"));
    return;
  }
  const uint32_t worker_count = static_cast<uint32_t>(workers_.size());
  // Only the job's owner or an admin may change it; a key that may not even see it is told the
  // job is unknown. True when the request was refused (and answered).
  auto refuse_unless_manager = [&](const std::string& id, const char* action) {
    const std::string* owner = jobs_.owner_of(id);
    if (!owner) return false;  // unknown: the handler says so
    if (!may_see(*owner, delivery.user)) {
      reply(peer, error_frames(not_visible(id), id));
      return true;
    }
    if (may_manage(*owner, delivery.user)) return false;
    complain("client", delivery.user,
             fmt::format("{} may not {} job {} of key '{}'; refused", label, action,
                         protocol::printable(id), protocol::printable(*owner)));
    reply(peer, error_frames(not_owner(id, *owner, action), id));
    return true;
  };
  try {
    if (const auto* hello = msg.as<wire::Hello>()) {
      if (hello->role() == wire::ROLE_WORKER) {
        reply(peer,
              error_frames("this is the client endpoint; workers connect to the worker endpoint"));
        return;
      }
      wire::Welcome welcome;
      welcome.set_build(protocol::kBuildVersion);
      welcome.set_heartbeat_interval_ms(static_cast<uint32_t>(options_.heartbeat.interval.count()));
      welcome.set_liveness(static_cast<uint32_t>(options_.heartbeat.liveness));
      reply(peer, encode(std::move(welcome)));
    } else if (auto* submit = msg.as_mutable<wire::SubmitJob>()) {
      // Checked and stored on the submissions' thread; admitted and answered by
      // admit_submissions() once ready.
      // The queue and the bundle's size and file count are checked here, before anything is
      // queued; the scene's figures on the thread.
      const SubmissionFigures figures = bundle_figures(*submit);
      std::optional<std::string> refusal =
          check_queue(jobs_.active_jobs() + submissions_->in_flight(), options_.limits);
      if (!refusal) refusal = check_figures(figures, options_.limits);
      if (!refusal) {
        wire::SubmitJob job;
        job.Swap(submit);
        if (!submissions_->add(peer, label, delivery.user, std::move(job), figures.bundle_bytes)) {
          refusal = fmt::format(
              "the master is busy checking other submissions (at most {} wait, {} per key, {} "
              "per connection); submit again in a moment",
              kMaxSubmissionsInFlight, kMaxSubmissionsPerKey, kMaxSubmissionsPerPeer);
        }
      }
      if (refusal) {
        log()->log(refusal_log_.take(delivery.user) ? spdlog::level::warn : spdlog::level::debug,
                   "job refused from {}: {}", label, *refusal);
        wire::SubmitReply out;
        out.set_error(*refusal);
        reply(peer, encode(std::move(out)));
      }
    } else if (const auto* request = msg.as<wire::StatusRequest>()) {
      const std::string* owner = jobs_.owner_of(request->job_id());
      if (owner && !may_see(*owner, delivery.user)) {
        reply(peer, error_frames(not_visible(request->job_id()), request->job_id()));
      } else if (auto st = jobs_.status(request->job_id(), worker_count)) {
        reply(peer, encode(std::move(*st)));
      } else {
        reply(peer, error_frames("unknown job '" + protocol::printable(request->job_id()) + "'",
                                 request->job_id()));
      }
    } else if (msg.as<wire::ListJobs>()) {
      wire::JobList list;
      for (auto& st : jobs_.list(worker_count)) {
        if (!may_see(st.owner(), delivery.user)) continue;
        st.set_protocol_version(protocol::kProtocolVersion);
        *list.add_jobs() = std::move(st);
      }
      reply(peer, encode(std::move(list)));
    } else if (const auto* cancel = msg.as<wire::CancelJob>()) {
      if (refuse_unless_manager(cancel->job_id(), "cancel")) return;
      if (auto state = jobs_.cancel(cancel->job_id())) {
        wire::CancelReply out;
        out.set_job_id(cancel->job_id());
        out.set_state(*state);
        reply(peer, encode(std::move(out)));
      } else {
        reply(peer, error_frames("unknown job '" + protocol::printable(cancel->job_id()) + "'",
                                 cancel->job_id()));
      }
    } else if (msg.as<wire::ListWorkers>()) {
      reply(peer, encode(worker_list()));
    } else if (const auto* remove = msg.as<wire::RemoveJob>()) {
      if (refuse_unless_manager(remove->job_id(), "remove")) return;
      try {
        jobs_.remove(remove->job_id());
        wire::RemoveReply out;
        out.set_job_id(remove->job_id());
        reply(peer, encode(std::move(out)));
      } catch (const JobRejected& e) {
        reply(peer, error_frames(jobs_.for_clients(e.what()), remove->job_id()));
      }
    } else if (const auto* retry = msg.as<wire::RetryJob>()) {
      if (refuse_unless_manager(retry->job_id(), "retry")) return;
      try {
        wire::RetryReply out;
        out.set_state(jobs_.retry(retry->job_id()));
        out.set_job_id(retry->job_id());
        reply(peer, encode(std::move(out)));
        dispatch();
      } catch (const JobRejected& e) {
        reply(peer, error_frames(jobs_.for_clients(e.what()), retry->job_id()));
      }
    } else if (const auto* fetch = msg.as<wire::FetchImage>()) {
      const std::string* owner = jobs_.owner_of(fetch->job_id());
      if (owner && !may_see(*owner, delivery.user)) {
        reply(peer, error_frames(not_visible(fetch->job_id()), fetch->job_id()));
        return;
      }
      try {
        reply(peer, encode(jobs_.image(fetch->job_id())));
      } catch (const JobRejected& e) {
        reply(peer, error_frames(jobs_.for_clients(e.what()), fetch->job_id()));
      }
    } else {
      complain("client", delivery.user,
               fmt::format("unexpected {} from {}; ignored", msg.type, label));
      reply(peer, error_frames("unexpected message " + msg.type + " on the client endpoint"));
    }
  } catch (const std::exception& e) {
    log()->error("client socket: failed to handle {} from {}: {}", msg.type, label, e.what());
    reply(peer, error_frames(jobs_.for_clients(
                    std::string("the master failed to handle the request: ") + e.what())));
  }
}

wire::WorkerList Broker::worker_list() const {
  wire::WorkerList list;
  const auto now = Clock::now();
  for (const auto& [peer, w] : workers_) {
    wire::WorkerInfo* info = list.add_workers();
    info->set_id(net::peer_label(peer));
    info->set_name(w.name);
    info->set_key_name(protocol::printable(w.key_name));
    info->set_threads(w.threads);
    for (const std::string& unit : jobs_.units_of(peer)) info->add_units(unit);
    info->set_units_done(w.units_merged);
    const double working = std::chrono::duration<double>(w.last_result - w.working_since).count();
    info->set_samples_per_second(w.units_merged > 0 && working > 0 ? w.samples_merged / working
                                                                   : 0.0);
    info->set_last_seen_seconds(std::chrono::duration<double>(now - w.heard).count());
    info->set_build(w.build);
  }
  return list;
}

}  // namespace rayfarm::master
