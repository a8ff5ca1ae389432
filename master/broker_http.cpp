// The reactor's side of the HTTP endpoint (http_feed.h): publishing snapshots of the farm while
// someone looks, and answering the calls the HTTP threads post, with the same rights as the
// client socket (broker_clients.cpp).
#include <fmt/format.h>

#include "common/protocol/codec.h"
#include "common/util/log.h"
#include "master/broker.h"
#include "master/peer_limits.h"

namespace rayfarm::master {
namespace protocol = rayfarm::protocol;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("master"); }

HttpAnswer failure(int status, std::string error) {
  HttpAnswer a;
  a.status = status;
  a.error = std::move(error);
  return a;
}

/// The HTTP status of a refusal's code.
int http_status(wire::Error::Code code) {
  switch (code) {
    case wire::Error::BAD_REQUEST:
      return 400;
    case wire::Error::NOT_FOUND:
      return 404;
    case wire::Error::FORBIDDEN:
      return 403;
    case wire::Error::REFUSED:
      return 409;
    case wire::Error::BUSY:
      return 429;
    default:
      return 500;
  }
}

template <class M>
HttpAnswer success(M message) {
  HttpAnswer a;
  a.message = std::make_shared<M>(std::move(message));
  return a;
}

}  // namespace

void Broker::serve_http() {
  metrics().workers_connected.set(static_cast<double>(workers_.size()));
  if (!http_) return;
  const auto now = Clock::now();
  if (http_feed_.snapshot_due(now)) {
    try {
      FarmSnapshot snap;
      const uint32_t worker_count = static_cast<uint32_t>(workers_.size());
      for (auto& st : jobs_.list(worker_count)) *snap.jobs.add_jobs() = std::move(st);
      snap.workers = worker_list();
      snap.taken = now;
      http_feed_.publish(std::move(snap));
    } catch (const std::exception& e) {
      log()->error("cannot publish the farm's state for the HTTP endpoint: {}", e.what());
    }
  }
  bool changed = false;
  for (HttpFeed::Pending& p : http_feed_.take_calls()) {
    try {
      p.answer.set_value(answer_http(p.call, changed));
    } catch (const std::exception& e) {
      log()->error("HTTP call for job {} failed: {}", protocol::printable(p.call.job_id), e.what());
      p.answer.set_value(failure(500, jobs_.for_clients(std::string("the master failed: ") +
                                                        e.what())));
    }
  }
  if (changed) dispatch();  // a job resumed or raised may serve the workers that wait
}

HttpAnswer Broker::answer_http(const HttpCall& call, bool& changed) {
  using Kind = HttpCall::Kind;
  const std::string& user = call.user.key_name;
  const std::string* key = call.user.authenticated ? &user : nullptr;
  // Answered in broker_requests.cpp, as on the client socket.
  auto answered = [](const RequestAnswer& a) {
    if (a.reply) {
      HttpAnswer out;
      out.message = a.reply;
      return out;
    }
    return failure(http_status(a.code), a.error);
  };
  if (call.kind == Kind::kDetail) return answered(job_detail(call.job_id, key));
  if (call.kind == Kind::kDrainWorker || call.kind == Kind::kDisableWorker ||
      call.kind == Kind::kEnableWorker) {
    wire::ChangeWorker request;
    request.set_worker(call.job_id);
    request.set_control(call.kind == Kind::kDrainWorker     ? wire::ChangeWorker::DRAIN
                        : call.kind == Kind::kDisableWorker ? wire::ChangeWorker::DISABLE
                                                            : wire::ChangeWorker::ENABLE);
    return answered(change_worker(request, key, changed));
  }
  const std::string& id = call.job_id;
  const std::string unknown = "unknown job '" + protocol::printable(id) + "'";
  const std::string* owner = jobs_.owner_of(id);
  // The client socket's rules, for the token's key; without a token a job is visible unless
  // the master keeps jobs private, and nothing may be changed.
  if (!owner || !rights_.may_see(*owner, key)) return failure(404, unknown);
  if (call.kind == Kind::kStatus) {
    auto st = jobs_.status(id, static_cast<uint32_t>(workers_.size()));
    if (!st) return failure(404, unknown);
    return success(std::move(*st));
  }
  if (!rights_.may_manage(*owner, key)) {
    metrics().refusals.add("http_forbidden");
    return failure(403, fmt::format("job {} belongs to key '{}': only that key or an admin key "
                                    "(rayfarm-master --admin-clients) may change it",
                                    protocol::printable(id), protocol::printable(*owner)));
  }
  // Within the key's budget of changes, as on the client socket (change_budget.h).
  if (auto refusal = jobs_.take_change(user)) {
    metrics().refusals.add("change_budget");
    return failure(429, *refusal);
  }
  if (call.kind == Kind::kCancel) {
    auto state = jobs_.cancel(id, user);
    if (!state) return failure(404, unknown);
    log()->info("job {} cancelled over HTTP by key '{}'", protocol::printable(id),
                protocol::printable(user));
    wire::CancelReply out;
    out.set_job_id(id);
    out.set_state(*state);
    return success(std::move(out));
  }
  if (call.kind == Kind::kRetry || call.kind == Kind::kRemove) {
    try {
      if (call.kind == Kind::kRemove) {
        jobs_.remove(id);
        log()->info("job {} removed over HTTP by key '{}'", protocol::printable(id),
                    protocol::printable(user));
        wire::RemoveReply out;
        out.set_job_id(id);
        return success(std::move(out));
      }
      // A retried job (each retried frame of a sequence) joins the queue again: within its limit.
      if (auto full = check_queue(jobs_.active_jobs() + submissions_->jobs_in_flight(),
                                  options_.limits, jobs_.retry_count(id))) {
        return failure(409, *full);
      }
      wire::RetryReply out;
      out.set_state(jobs_.retry(id, user));
      out.set_job_id(id);
      log()->info("job {} queued again over HTTP by key '{}'", protocol::printable(id),
                  protocol::printable(user));
      changed = true;
      return success(std::move(out));
    } catch (const JobRejected& e) {
      return failure(409, jobs_.for_clients(e.what()));
    }
  }
  std::optional<int32_t> priority;
  std::optional<bool> paused;
  if (call.kind == Kind::kPriority) {
    if (auto refusal = priority_refusal(call.priority, user)) {
      metrics().refusals.add("http_forbidden");
      return failure(403, *refusal);
    }
    priority = call.priority;
  } else {
    paused = call.kind == Kind::kPause;
  }
  try {
    const JobRecord* r = jobs_.change(id, priority, paused, user);
    if (r == nullptr) return failure(404, unknown);
    changed = true;
    wire::ChangeJobReply out;
    out.set_job_id(id);
    out.set_state(r->state);
    out.set_priority(r->priority);
    out.set_paused(r->paused);
    return success(std::move(out));
  } catch (const JobRejected& e) {
    return failure(409, jobs_.for_clients(e.what()));
  }
}

}  // namespace rayfarm::master
