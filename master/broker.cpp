#include "master/broker.h"

#include <algorithm>
#include <array>
#include <vector>

#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/protocol/version.h"
#include "common/util/log.h"
#include "master/wire_replies.h"

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

/// What one connection can make the master queue (docs/reliability.md): messages per peer in each
/// direction on each socket. A client sends one request and reads its reply; a worker has at most
/// kMaxWants units, a few results and heartbeats in flight.
constexpr net::QueueBounds kWorkerQueues{/*send=*/64, /*receive=*/16};
constexpr net::QueueBounds kClientQueues{/*send=*/8, /*receive=*/4};
/// A worker connection gets one bundle at most once per window, and bundles of at most twice the
/// bundle limit in all per window.
constexpr auto kBundleWindow = std::chrono::seconds{60};

}  // namespace

Broker::Broker(MasterOptions options)
    : options_(std::move(options)),
      rights_{options_.security.private_jobs, options_.security.admin_clients},
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
      gate_(AccessGate::open(options_)),
      workers_socket_(options_.worker_endpoint, options_.limits.max_message_bytes,
                      curve_for(options_, kWorkerDomain), kWorkerQueues),
      clients_socket_(options_.client_endpoint, options_.limits.max_message_bytes,
                      curve_for(options_, kClientDomain), kClientQueues),
      next_heartbeat_(Clock::now()) {
  submissions_ = std::make_unique<SubmissionQueue>(jobs_, options_.limits);
  const size_t restarted = jobs_.recover();
  if (!options_.http_endpoint.empty()) {
    tokens_ = std::make_unique<HttpTokens>(options_.data_dir);
    HttpOptions http;
    http.endpoint = options_.http_endpoint;
    http.keys = options_.security.key.has_value();
    http.rights = rights_;
    http.jobs_dir = options_.data_dir / "jobs";
    if (gate_) {
      AccessGate* gate = gate_.get();
      http.name_of = [gate](const std::string& key) { return gate->client_name_of(key); };
    }
    // Jobs are read without a token on this machine only, unless asked.
    http.anonymous_read = options_.http_anonymous_read ||
                          net::is_loopback_endpoint("tcp://" + options_.http_endpoint);
    http.build = protocol::kBuildVersion;
    try {
      http_ = std::make_unique<HttpServer>(std::move(http), http_feed_, *tokens_);
    } catch (const std::exception& e) {
      if (!options_.http_endpoint_is_default) throw;
      log()->warn("no dashboard: {} (give --http-endpoint HOST:PORT to choose another)", e.what());
      tokens_.reset();
    }
  }
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
  Clock::time_point woke = Clock::now();  // busy from here until the next poll
  while (!stop.load()) {
    const auto now = Clock::now();
    busy_.fetch_add((now - woke).count(), std::memory_order_relaxed);
    metrics().reactor_busy_seconds.add(std::chrono::duration<double>(now - woke).count());
    const auto until_heartbeat = std::chrono::duration_cast<milliseconds>(next_heartbeat_ - now);
    const auto wait = std::clamp(until_heartbeat, milliseconds{0}, milliseconds{100});
    const auto readable = net::poll(sockets, wait);
    polls_.fetch_add(1, std::memory_order_relaxed);
    listened_ = woke = Clock::now();
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
    serve_http();
    memory_return_.tick();
    message_bounds_.prune(workers_);
  }
  // Calls the HTTP side still waits on, and those to come, are answered at once.
  http_feed_.close();
  busy_.fetch_add((Clock::now() - woke).count(), std::memory_order_relaxed);
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
    remove_worker(peer, fmt::format("lost: silent for {:.1f} s", silent), Departure::kLost);
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
    peer_log(PeerLog::kHello, "worker", peer, key_name, spdlog::level::warn,
             fmt::format("worker socket: {} said hello as a client; refused",
                         net::peer_label(peer)));
    send_worker(
        peer, error_frames(wire::Error::WRONG_ENDPOINT,
                           "this is the worker endpoint; clients connect to the client endpoint"));
    return;
  }
  // A connection that says hello again keeps a drain or disable it was given, whatever name it
  // gives now.
  WorkerControl before = WorkerControl::kEnabled;
  if (auto known = workers_.find(peer); known != workers_.end()) {
    before = known->second.control;
    jobs_.release_worker(peer);  // a worker that starts over holds nothing any more
  } else {
    metrics().workers_joined.add();
  }
  Worker& w = workers_[peer];
  w.name = hello.name().empty() ? "unnamed" : protocol::printable(hello.name());
  w.threads = hello.threads();
  w.key_name = key_name;  // as the ZAP handler named it: leases and failures go by it
  w.build = protocol::printable(hello.build());
  // A worker drained or disabled keeps it when it reconnects under the same key and name.
  const auto remembered = controls_.find(std::make_pair(w.key_name, w.name));
  w.control = std::max(
      before, remembered == controls_.end() ? WorkerControl::kEnabled : remembered->second);
  heard_from(w);
  w.wants = 0;
  peer_log(PeerLog::kHello, "worker", peer, key_name, spdlog::level::info,
           fmt::format("{} joined{}: {} threads, {}; {} worker{} connected{}", worker_label(peer),
                       key_name.empty() ? "" : " with key '" + protocol::printable(key_name) + "'",
                       w.threads,
                       hello.build().empty() ? "unknown build" : protocol::printable(hello.build()),
                       workers_.size(), workers_.size() == 1 ? "" : "s",
                       w.control == WorkerControl::kDraining   ? "; it stays drained"
                       : w.control == WorkerControl::kDisabled ? "; it stays disabled"
                                                               : ""));
  wire::Welcome welcome;
  welcome.set_build(protocol::kBuildVersion);
  welcome.set_heartbeat_interval_ms(static_cast<uint32_t>(options_.heartbeat.interval.count()));
  welcome.set_liveness(static_cast<uint32_t>(options_.heartbeat.liveness));
  send_worker(peer, encode(std::move(welcome)));
}

void Broker::remove_worker(const net::PeerId& peer, const std::string& why, Departure departure) {
  auto it = workers_.find(peer);
  if (it == workers_.end()) return;
  const std::string label = worker_label(peer);
  const std::string key = it->second.key_name;
  const size_t requeued = jobs_.release_worker(peer);
  metrics().units_requeued.add(static_cast<double>(requeued));
  (departure == Departure::kLost ? metrics().workers_lost : metrics().workers_left).add();
  workers_.erase(it);
  const auto level = departure == Departure::kLost ? spdlog::level::warn : spdlog::level::info;
  peer_log(PeerLog::kDeparture, "worker", peer, key, level,
           fmt::format("{} {}; {} unit{} requeued; {} worker{} connected", label, why, requeued,
                       requeued == 1 ? "" : "s", workers_.size(),
                       workers_.size() == 1 ? "" : "s"));
  if (requeued) dispatch();
}

void Broker::dispatch() {
  // One unit per asking worker per round, so that scarce units spread over the workers.
  std::vector<net::PeerId> unreachable;
  bool sent = true;
  while (sent && jobs_.has_pending()) {
    sent = false;
    for (auto& [peer, w] : workers_) {
      if (w.wants == 0 || w.control != WorkerControl::kEnabled) continue;
      auto unit = jobs_.next_unit(peer, w.key_name);
      if (!unit) continue;  // e.g. blocked from the jobs that have units
      message_bounds_.leased(peer, *unit);
      if (!workers_socket_.send(peer, encode(std::move(*unit)))) {
        unreachable.push_back(peer);
        w.wants = 0;
        continue;
      }
      --w.wants;
      metrics().units_leased.add();
      sent = true;
    }
  }
  for (const auto& peer : unreachable) remove_worker(peer, "unreachable (disconnected)");
}

void Broker::handle_worker(const net::Delivery& delivery) {
  const net::PeerId& peer = delivery.peer;
  {
    size_t bytes = 0;
    for (const auto& f : delivery.frames) bytes += f.size();
    metrics().worker_bytes_received.add(static_cast<double>(bytes));
    // Dropped before it is decoded (and held a second time) when no unit of this connection
    // could make a message that large.
    if (const uint64_t bound = message_bounds_.bound(peer); bytes > bound) {
      metrics().refusals.add("worker_message_size");
      complain(PeerLog::kMalformed, "worker", delivery,
               fmt::format("dropped a message of {} bytes from {}: the units leased to it make "
                           "messages of at most {} bytes",
                           bytes, worker_label(peer), bound));
      return;
    }
  }
  protocol::Decoded msg;
  try {
    msg = protocol::decode(delivery.frames);
  } catch (const protocol::DecodeError& e) {
    complain(PeerLog::kMalformed, "worker", delivery,
             fmt::format("ignored a bad message from {}: {}", worker_label(peer), e.what()));
    return;
  }
  if (!msg.version_ok()) {
    complain(PeerLog::kProtocolVersion, "worker", delivery,
             fmt::format("refused {} ({}): it speaks protocol version {}, this master {}",
                         worker_label(peer), msg.type, msg.version, protocol::kProtocolVersion));
    send_worker(peer, refusal_frames(msg.version, "worker"));
    metrics().refusals.add("protocol_version");
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
      const auto merge_start = Clock::now();
      const MergeOutcome outcome = jobs_.on_result(peer, *result, delivery.user);
      Metrics& m = metrics();
      m.merge_seconds.observe(std::chrono::duration<double>(Clock::now() - merge_start).count());
      switch (outcome) {
        case MergeOutcome::kMerged:
          m.units_merged.add();
          m.unit_seconds.observe(std::clamp(result->render_seconds(), 0.0, 86400.0));
          break;
        case MergeOutcome::kDuplicate: m.units_duplicate.add(); break;
        case MergeOutcome::kRejected: m.units_rejected.add(); break;
        case MergeOutcome::kUnleased: m.units_unleased.add(); break;
        case MergeOutcome::kDiscarded: m.units_discarded_job_finished.add(); break;
      }
      if (outcome == MergeOutcome::kUnleased) {
        complain(PeerLog::kResultDropped, "worker", delivery,
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
        const double samples = double(t.x1() - t.x0()) * double(t.y1() - t.y0()) *
                               double(result->sample_end() - result->sample_begin());
        w.samples_merged += samples;
        m.samples_merged.add(samples);
      }
      if (it == workers_.end()) {
        send_worker(peer,
                    error_frames(wire::Error::UNKNOWN_WORKER, "unknown worker: send Hello first"));
      }
      dispatch();
      return;
    }
    if (it == workers_.end()) {
      if (msg.as<wire::Goodbye>()) return;
      peer_log(PeerLog::kNotRegistered, "worker", peer, delivery.user, spdlog::level::debug,
               fmt::format("worker socket: {} from unknown {}; asking it to say hello", msg.type,
                           net::peer_label(peer)));
      send_worker(peer,
                  error_frames(wire::Error::UNKNOWN_WORKER, "unknown worker: send Hello first"));
      return;
    }
    Worker& w = it->second;
    if (msg.as<wire::Heartbeat>()) return;
    if (msg.as<wire::WorkRequest>()) {
      w.wants = std::min(w.wants + 1, kMaxWants);
      dispatch();
    } else if (const auto* failed = msg.as<wire::UnitFailed>()) {
      metrics().units_failed.add();
      if (jobs_.on_unit_failed(peer, *failed, delivery.user)) {
        metrics().units_requeued.add();
      } else {
        complain(PeerLog::kUnitFailed, "worker", delivery,
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
      complain(PeerLog::kUnexpected, "worker", delivery,
               fmt::format("unexpected {} from {}; ignored", msg.type, worker_label(peer)));
      send_worker(peer, error_frames(wire::Error::BAD_REQUEST,
                                     "unexpected message " + msg.type + " on the worker endpoint"));
    }
  } catch (const std::exception& e) {
    log()->error("worker socket: failed to handle {} from {}: {}", msg.type, worker_label(peer),
                 e.what());
  }
}

void Broker::peer_log(PeerLog kind, const std::string& socket, const net::PeerId& peer,
                      const std::string& key, spdlog::level::level_enum level,
                      const std::string& text) {
  // Keys are counted per socket (the two allow-lists may name keys alike); without keys, each
  // connection is its own.
  const std::string who =
      socket + (key.empty() ? " connection " + net::peer_label(peer) : " key " + key);
  const LogBudget::Verdict verdict = peer_logs_.take(kind, who);
  log()->log(verdict.log ? level : spdlog::level::trace, "{}{}", text, verdict.suffix());
}

void Broker::complain(PeerLog kind, const std::string& socket, const net::Delivery& delivery,
                      const std::string& text) {
  peer_log(kind, socket, delivery.peer, delivery.user, spdlog::level::warn,
           socket + " socket: " + text);
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
    peer_log(PeerLog::kBundleRequest, "worker", peer, w.key_name, spdlog::level::info,
             fmt::format("bundle {} not sent to {}: the master has no such bundle",
                         protocol::printable(hash.substr(0, 12)), worker_label(peer)));
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
    peer_log(PeerLog::kBundleRequest, "worker", peer, w.key_name, spdlog::level::warn,
             fmt::format("bundle {} not sent to {}: {}", hash.substr(0, 12), worker_label(peer),
                         refusal));
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

}  // namespace rayfarm::master
