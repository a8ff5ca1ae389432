// The client socket: requests from the CLI (submit, status, list, cancel, remove, retry, fetch,
// workers), one reply each; who may see or change a job; submissions admitted once checked.
#include <optional>
#include <string>

#include "common/limits.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/util/log.h"
#include "master/broker.h"
#include "master/wire_replies.h"

namespace rayfarm::master {
namespace protocol = rayfarm::protocol;
using protocol::encode;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("master"); }

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

}  // namespace

void Broker::admit_submissions() {
  bool admitted = false;
  for (SubmissionQueue::Done& done : submissions_->take_done()) {
    wire::SubmitReply out;
    if (done.job) {
      try {
        out.set_job_id(jobs_.admit(std::move(*done.job)));
        admitted = true;
      } catch (const std::exception& e) {
        log()->error("job refused ({}) from {}: {}", done.scene, done.label, e.what());
        out.set_code(wire::Error::INTERNAL);
        out.set_error(jobs_.for_clients(e.what()));
      }
    } else {
      metrics().refusals.add("submission");
      log()->log(refusal_log_.take(done.user) ? spdlog::level::warn : spdlog::level::debug,
                 "job refused ({}) from {}: {}", done.scene, done.label, done.error);
      out.set_code(done.internal ? wire::Error::INTERNAL : wire::Error::REFUSED);
      out.set_error(jobs_.for_clients(done.error));
    }
    reply(done.peer, encode(std::move(out)));
  }
  if (admitted) dispatch();
}

std::optional<std::string> Broker::priority_refusal(int32_t priority,
                                                    const std::string& user) const {
  // Out of range: the job manager names it, for every key alike.
  const bool trusted = user.empty() || options_.security.admin_clients.count(user) != 0;
  const int32_t cap = options_.security.max_client_priority;
  if (trusted || priority <= cap) return std::nullopt;
  return fmt::format(
      "priority {} is above what key '{}' may give a job (at most {}; an admin key "
      "(rayfarm-master --admin-clients) may go to {}, and --max-client-priority raises the "
      "limit)",
      priority, protocol::printable(user), cap, kMaxPriority);
}

void Broker::handle_client(const net::Delivery& delivery) {
  const net::PeerId& peer = delivery.peer;
  {
    size_t bytes = 0;
    for (const auto& f : delivery.frames) bytes += f.size();
    metrics().client_bytes_received.add(static_cast<double>(bytes));
    metrics().client_requests.add();
  }
  const std::string label =
      "client " + net::peer_label(peer) +
      (delivery.user.empty() ? "" : " (key '" + protocol::printable(delivery.user) + "')");
  protocol::Decoded msg;
  try {
    msg = protocol::decode(delivery.frames);
  } catch (const protocol::DecodeError& e) {
    complain("client", delivery.user,
             fmt::format("ignored a bad message from {}: {}", label, e.what()));
    reply(peer, error_frames(wire::Error::BAD_REQUEST,
                             std::string("cannot decode the request: ") + e.what()));
    return;
  }
  if (!msg.version_ok()) {
    complain("client", delivery.user,
             fmt::format("refused {} ({}): it speaks protocol version {}, this master {}", label,
                         msg.type, msg.version, protocol::kProtocolVersion));
    metrics().refusals.add("protocol_version");
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
      reply(peer, error_frames(wire::Error::NOT_FOUND, not_visible(id), id));
      return true;
    }
    if (may_manage(*owner, delivery.user)) return false;
    complain("client", delivery.user,
             fmt::format("{} may not {} job {} of key '{}'; refused", label, action,
                         protocol::printable(id), protocol::printable(*owner)));
    reply(peer, error_frames(wire::Error::FORBIDDEN, not_owner(id, *owner, action), id));
    return true;
  };
  try {
    if (const auto* hello = msg.as<wire::Hello>()) {
      if (hello->role() == wire::ROLE_WORKER) {
        reply(peer,
              error_frames(wire::Error::WRONG_ENDPOINT,
                           "this is the client endpoint; workers connect to the worker endpoint"));
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
          check_queue(jobs_.active_jobs() + submissions_->jobs_in_flight(), options_.limits,
                      protocol::frame_count(submit->frames()));
      wire::Error::Code code = wire::Error::REFUSED;
      if (!refusal) refusal = check_figures(figures, options_.limits);
      if (!refusal) refusal = priority_refusal(submit->priority(), delivery.user);
      if (!refusal) {
        wire::SubmitJob job;
        job.Swap(submit);
        if (!submissions_->add(peer, label, delivery.user, std::move(job), figures.bundle_bytes)) {
          code = wire::Error::BUSY;
          refusal = fmt::format(
              "the master is busy checking other submissions (at most {} wait, {} per key, {} "
              "per connection); submit again in a moment",
              kMaxSubmissionsInFlight, kMaxSubmissionsPerKey, kMaxSubmissionsPerPeer);
        }
      }
      if (refusal) {
        metrics().refusals.add(code == wire::Error::BUSY ? "submission_busy" : "submission");
        log()->log(refusal_log_.take(delivery.user) ? spdlog::level::warn : spdlog::level::debug,
                   "job refused from {}: {}", label, *refusal);
        wire::SubmitReply out;
        out.set_code(code);
        out.set_error(*refusal);
        reply(peer, encode(std::move(out)));
      }
    } else if (const auto* request = msg.as<wire::StatusRequest>()) {
      const std::string* owner = jobs_.owner_of(request->job_id());
      if (owner && !may_see(*owner, delivery.user)) {
        reply(peer, error_frames(wire::Error::NOT_FOUND, not_visible(request->job_id()),
                                 request->job_id()));
      } else if (auto st = jobs_.status(request->job_id(), worker_count)) {
        reply(peer, encode(std::move(*st)));
      } else {
        reply(peer, error_frames(wire::Error::NOT_FOUND,
                                 "unknown job '" + protocol::printable(request->job_id()) + "'",
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
        reply(peer, error_frames(wire::Error::NOT_FOUND,
                                 "unknown job '" + protocol::printable(cancel->job_id()) + "'",
                                 cancel->job_id()));
      }
    } else if (const auto* change = msg.as<wire::ChangeJob>()) {
      if (refuse_unless_manager(change->job_id(), "change")) return;
      if (change->has_priority() && jobs_.owner_of(change->job_id()) != nullptr) {
        if (auto refusal = priority_refusal(change->priority(), delivery.user)) {
          complain("client", delivery.user, fmt::format("{}: {}; refused", label, *refusal));
          reply(peer, error_frames(wire::Error::FORBIDDEN, *refusal, change->job_id()));
          return;
        }
      }
      try {
        const JobRecord* r = jobs_.change(
            change->job_id(),
            change->has_priority() ? std::optional<int32_t>(change->priority()) : std::nullopt,
            change->has_paused() ? std::optional<bool>(change->paused()) : std::nullopt);
        if (r == nullptr) {
          reply(peer, error_frames(wire::Error::NOT_FOUND,
                                   "unknown job '" + protocol::printable(change->job_id()) + "'",
                                   change->job_id()));
          return;
        }
        wire::ChangeJobReply out;
        out.set_job_id(change->job_id());
        out.set_state(r->state);
        out.set_priority(r->priority);
        out.set_paused(r->paused);
        reply(peer, encode(std::move(out)));
        dispatch();  // a job resumed or raised may serve the workers that wait
      } catch (const JobRejected& e) {
        reply(peer,
              error_frames(wire::Error::REFUSED, jobs_.for_clients(e.what()), change->job_id()));
      }
    } else if (msg.as<wire::TokenRequest>()) {
      // CURVE has proven the key this connection uses (without keys every client is the one
      // nameless user); the allow-list must still list it under the same name, since a
      // connection outlives a change of the list.
      const std::optional<std::string> listed =
          gate_ ? gate_->client_name_of(delivery.key) : std::optional<std::string>("");
      if (!tokens_) {
        reply(peer, error_frames(wire::Error::REFUSED,
                                 "this master serves no HTTP endpoint (--http-endpoint), so it "
                                 "has no tokens"));
      } else if (!listed || *listed != delivery.user) {
        reply(peer, error_frames(wire::Error::FORBIDDEN,
                                 "this client's key is no longer on the master's allow-list"));
      } else {
        wire::TokenReply out;
        out.set_token(tokens_->issue(delivery.user, delivery.key));
        out.set_key_name(protocol::printable(delivery.user));
        reply(peer, encode(std::move(out)));
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
        reply(peer, error_frames(jobs_.owner_of(remove->job_id()) ? wire::Error::REFUSED
                                                                  : wire::Error::NOT_FOUND,
                                 jobs_.for_clients(e.what()), remove->job_id()));
      }
    } else if (const auto* retry = msg.as<wire::RetryJob>()) {
      if (refuse_unless_manager(retry->job_id(), "retry")) return;
      // A retried job (each retried frame of a sequence) joins the queue again.
      if (auto full = check_queue(jobs_.active_jobs() + submissions_->jobs_in_flight(),
                                  options_.limits, jobs_.retry_count(retry->job_id()))) {
        reply(peer, error_frames(wire::Error::REFUSED, *full, retry->job_id()));
        return;
      }
      try {
        wire::RetryReply out;
        out.set_state(jobs_.retry(retry->job_id()));
        out.set_job_id(retry->job_id());
        reply(peer, encode(std::move(out)));
        dispatch();
      } catch (const JobRejected& e) {
        reply(peer, error_frames(jobs_.owner_of(retry->job_id()) ? wire::Error::REFUSED
                                                                 : wire::Error::NOT_FOUND,
                                 jobs_.for_clients(e.what()), retry->job_id()));
      }
    } else if (const auto* fetch = msg.as<wire::FetchImage>()) {
      const std::string* owner = jobs_.owner_of(fetch->job_id());
      if (owner && !may_see(*owner, delivery.user)) {
        reply(peer,
              error_frames(wire::Error::NOT_FOUND, not_visible(fetch->job_id()), fetch->job_id()));
        return;
      }
      try {
        reply(peer, encode(jobs_.image(fetch->job_id(), fetch->movie(), fetch->contact_sheet())));
      } catch (const JobRejected& e) {
        reply(peer,
              error_frames(wire::Error::NOT_FOUND, jobs_.for_clients(e.what()), fetch->job_id()));
      }
    } else {
      complain("client", delivery.user,
               fmt::format("unexpected {} from {}; ignored", msg.type, label));
      reply(peer, error_frames(wire::Error::BAD_REQUEST,
                               "unexpected message " + msg.type + " on the client endpoint"));
    }
  } catch (const std::exception& e) {
    log()->error("client socket: failed to handle {} from {}: {}", msg.type, label, e.what());
    reply(peer, error_frames(wire::Error::INTERNAL,
                             jobs_.for_clients(std::string("the master failed to handle the "
                                                           "request: ") +
                                               e.what())));
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
