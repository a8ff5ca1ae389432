// The client socket: requests from the CLI (submit, status, list, cancel, remove, retry, fetch,
// workers), one reply each; who may see or change a job; submissions admitted once checked.
#include <optional>
#include <string>
#include <string_view>

#include "common/image/exr_header.h"
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

/// The samples per pixel of the image in `exr`, from the `rayfarm:spp` attribute of its header
/// (common/image/film_output.cpp writes it); nullopt when the header has none or is not a
/// well-formed EXR header.
std::optional<uint32_t> exr_spp(std::string_view exr) {
  const auto attributes = peek_exr_attributes(exr);
  if (!attributes) return std::nullopt;
  for (const ExrAttribute& a : *attributes) {
    if (a.name != "rayfarm:spp" || a.type != "string") continue;
    if (a.value.empty() || a.value.size() > 10) return std::nullopt;
    uint64_t spp = 0;
    for (const char c : a.value) {
      if (c < '0' || c > '9') return std::nullopt;
      spp = spp * 10 + static_cast<uint64_t>(c - '0');
    }
    if (spp > UINT32_MAX) return std::nullopt;
    return static_cast<uint32_t>(spp);
  }
  return std::nullopt;
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
      peer_log(PeerLog::kSubmissionRefused, "client", done.peer, done.user, spdlog::level::warn,
               fmt::format("job refused ({}) from {}: {}", done.scene, done.label, done.error));
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
    complain(PeerLog::kMalformed, "client", delivery,
             fmt::format("ignored a bad message from {}: {}", label, e.what()));
    reply(peer, error_frames(wire::Error::BAD_REQUEST,
                             std::string("cannot decode the request: ") + e.what()));
    return;
  }
  if (!msg.version_ok()) {
    complain(PeerLog::kProtocolVersion, "client", delivery,
             fmt::format("refused {} ({}): it speaks protocol version {}, this master {}", label,
                         msg.type, msg.version, protocol::kProtocolVersion));
    metrics().refusals.add("protocol_version");
    reply(peer, refusal_frames(msg.version, "client"));
    return;
  }
  const uint32_t worker_count = static_cast<uint32_t>(workers_.size());
  // Every request about a job first: a job that does not exist and, under --private-jobs, one
  // this key may not see get the same answer (no_such_job), whatever the request. True when the
  // request was refused (and answered).
  auto refuse_unless_visible = [&](const std::string& id) {
    const std::string* owner = jobs_.owner_of(id);
    if (owner && may_see(*owner, delivery.user)) return false;
    reply(peer, error_frames(wire::Error::NOT_FOUND, no_such_job(id, rights_.private_jobs), id));
    return true;
  };
  // A change costs the master work (a record on disk, a log line): each key has a budget of
  // them (change_budget.h), counted in the refusals' metric past it.
  auto refuse_over_budget = [&](const std::string& id) {
    const std::optional<std::string> refusal = jobs_.take_change(delivery.user);
    if (!refusal) return false;
    metrics().refusals.add("change_budget");
    reply(peer, error_frames(wire::Error::BUSY, *refusal, id));
    return true;
  };
  // A request answered in broker_requests.cpp, for the HTTP endpoint too.
  auto send_answer = [&](const RequestAnswer& a) {
    if (a.reply) {
      reply(peer, protocol::encode_raw(*a.reply));
      return;
    }
    if (a.code == wire::Error::FORBIDDEN) {
      complain(PeerLog::kForbidden, "client", delivery,
               fmt::format("{}: {}; refused", label, a.error));
    }
    reply(peer, error_frames(a.code, a.error, a.job_id));
  };
  // Only the job's owner or an admin may change it, within its key's budget. True when the
  // request was refused (and answered).
  auto refuse_unless_manager = [&](const std::string& id, const char* action) {
    if (refuse_unless_visible(id)) return true;
    const std::string* owner = jobs_.owner_of(id);
    if (may_manage(*owner, delivery.user)) return refuse_over_budget(id);
    complain(PeerLog::kForbidden, "client", delivery,
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
        peer_log(PeerLog::kSubmissionRefused, "client", peer, delivery.user, spdlog::level::warn,
                 fmt::format("job refused from {}: {}", label, *refusal));
        wire::SubmitReply out;
        out.set_code(code);
        out.set_error(*refusal);
        reply(peer, encode(std::move(out)));
      }
    } else if (const auto* request = msg.as<wire::StatusRequest>()) {
      if (refuse_unless_visible(request->job_id())) return;
      if (auto st = jobs_.status(request->job_id(), worker_count)) {
        reply(peer, encode(std::move(*st)));
      } else {
        reply(peer, error_frames(wire::Error::NOT_FOUND,
                                 no_such_job(request->job_id(), rights_.private_jobs),
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
      if (auto state = jobs_.cancel(cancel->job_id(), delivery.user)) {
        wire::CancelReply out;
        out.set_job_id(cancel->job_id());
        out.set_state(*state);
        reply(peer, encode(std::move(out)));
      } else {
        reply(peer, error_frames(wire::Error::NOT_FOUND,
                                 no_such_job(cancel->job_id(), rights_.private_jobs),
                                 cancel->job_id()));
      }
    } else if (const auto* change = msg.as<wire::ChangeJob>()) {
      if (refuse_unless_manager(change->job_id(), "change")) return;
      if (change->has_priority() && jobs_.owner_of(change->job_id()) != nullptr) {
        if (auto refusal = priority_refusal(change->priority(), delivery.user)) {
          complain(PeerLog::kForbidden, "client", delivery,
                   fmt::format("{}: {}; refused", label, *refusal));
          reply(peer, error_frames(wire::Error::FORBIDDEN, *refusal, change->job_id()));
          return;
        }
      }
      try {
        const JobRecord* r = jobs_.change(
            change->job_id(),
            change->has_priority() ? std::optional<int32_t>(change->priority()) : std::nullopt,
            change->has_paused() ? std::optional<bool>(change->paused()) : std::nullopt,
            delivery.user);
        if (r == nullptr) {
          reply(peer, error_frames(wire::Error::NOT_FOUND,
                                   no_such_job(change->job_id(), rights_.private_jobs),
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
      reply(peer, encode(worker_list(&delivery.user)));
    } else if (const auto* detail = msg.as<wire::JobDetailRequest>()) {
      send_answer(job_detail(detail->job_id(), &delivery.user));
    } else if (const auto* change_worker_request = msg.as<wire::ChangeWorker>()) {
      bool changed = false;
      send_answer(change_worker(*change_worker_request, &delivery.user, changed));
      if (changed) dispatch();
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
        out.set_state(jobs_.retry(retry->job_id(), delivery.user));
        out.set_job_id(retry->job_id());
        reply(peer, encode(std::move(out)));
        dispatch();
      } catch (const JobRejected& e) {
        reply(peer, error_frames(jobs_.owner_of(retry->job_id()) ? wire::Error::REFUSED
                                                                 : wire::Error::NOT_FOUND,
                                 jobs_.for_clients(e.what()), retry->job_id()));
      }
    } else if (const auto* fetch = msg.as<wire::FetchImage>()) {
      if (refuse_unless_visible(fetch->job_id())) return;
      try {
        wire::ImageData image =
            jobs_.image(fetch->job_id(), fetch->movie(), fetch->contact_sheet());
        if (!image.exr().empty()) describe_image(image, worker_count);
        reply(peer, encode(std::move(image)));
      } catch (const JobRejected& e) {
        reply(peer,
              error_frames(wire::Error::NOT_FOUND, jobs_.for_clients(e.what()), fetch->job_id()));
      }
    } else {
      complain(PeerLog::kUnexpected, "client", delivery,
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

void Broker::describe_image(wire::ImageData& image, uint32_t worker_count) const {
  // The image is the newest one on disk, which lags the job's merged film: by up to an image
  // interval while it runs, and for as long as storage fails. Its figures are its own, from its
  // header; the job's go beside them, with the reason when they differ.
  const uint32_t job_spp = image.spp_done();
  image.set_job_spp_done(job_spp);
  const std::optional<uint32_t> spp = exr_spp(image.exr());
  if (!spp) {
    image.set_image_note(fmt::format(
        "the image does not say how many samples per pixel it holds (no rayfarm:spp in its "
        "header); the job is at {} spp",
        job_spp));
    return;
  }
  image.set_spp_done(*spp);
  if (*spp == job_spp) return;
  const auto st = jobs_.status(image.job_id(), worker_count);
  if (st && !st->storage_error().empty()) {
    image.set_image_note("the master cannot write the job's newer image now: " +
                         st->storage_error());
  } else {
    image.set_image_note("the job's newer image is written at its next image interval");
  }
}

wire::WorkerList Broker::worker_list(const std::string* user) const {
  wire::WorkerList list;
  for (const auto& [peer, w] : workers_) *list.add_workers() = worker_info(peer, w, user);
  return list;
}

wire::WorkerInfo Broker::worker_info(const net::PeerId& peer, const Worker& w,
                                     const std::string* user) const {
  const auto now = Clock::now();
  wire::WorkerInfo out;
  wire::WorkerInfo* info = &out;
  {
    info->set_id(net::peer_label(peer));
    info->set_name(w.name);
    info->set_key_name(protocol::printable(w.key_name));
    info->set_threads(w.threads);
    const std::vector<std::string> held = jobs_.units_of(peer);
    for (const std::string& unit : held) {
      // A unit names its job ("JOB/UNIT"): for a client, only those of the jobs it may see,
      // as the HTTP endpoint shows them.
      if (user) {
        const std::string* owner = jobs_.owner_of(unit.substr(0, unit.find('/')));
        if (!owner || !may_see(*owner, *user)) continue;
      }
      info->add_units(unit);
    }
    info->set_units_done(w.units_merged);
    const double working = std::chrono::duration<double>(w.last_result - w.working_since).count();
    info->set_samples_per_second(w.units_merged > 0 && working > 0 ? w.samples_merged / working
                                                                   : 0.0);
    info->set_last_seen_seconds(std::chrono::duration<double>(now - w.heard).count());
    info->set_build(w.build);
    // "drained" from every unit it holds, also those of jobs this user may not see: a worker
    // still rendering another key's units is not ready to be shut down.
    info->set_control(w.control == WorkerControl::kEnabled ? "enabled"
                      : w.control == WorkerControl::kDisabled
                          ? "disabled"
                          : (held.empty() ? "drained" : "draining"));
  }
  return out;
}

}  // namespace rayfarm::master
