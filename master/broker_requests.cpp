// Requests that the client socket (broker_clients.cpp) and the HTTP endpoint (broker_http.cpp)
// both serve, answered once here with one rule of who may see and change what: a job's detail
// view, and the controls of a worker (drain, disable, enable).
#include <fmt/format.h>

#include "common/protocol/codec.h"
#include "common/util/log.h"
#include "master/broker.h"
#include "master/wire_replies.h"

namespace rayfarm::master {
namespace protocol = rayfarm::protocol;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("master"); }

RequestAnswer refused(wire::Error::Code code, std::string error, std::string job = {}) {
  RequestAnswer a;
  a.code = code;
  a.error = std::move(error);
  a.job_id = std::move(job);
  return a;
}

const char* control_verb(wire::ChangeWorker::Control c) {
  switch (c) {
    case wire::ChangeWorker::DRAIN:
      return "drained";
    case wire::ChangeWorker::DISABLE:
      return "disabled";
    default:
      return "enabled";
  }
}

}  // namespace

RequestAnswer Broker::job_detail(const std::string& id, const std::string* user) const {
  const std::string* owner = jobs_.owner_of(id);
  if (!owner || !rights_.may_see(*owner, user)) {
    return refused(wire::Error::NOT_FOUND, no_such_job(id, rights_.private_jobs), id);
  }
  auto detail = jobs_.detail(id, static_cast<uint32_t>(workers_.size()));
  if (!detail) return refused(wire::Error::NOT_FOUND, no_such_job(id, rights_.private_jobs), id);
  detail->set_protocol_version(protocol::kProtocolVersion);
  RequestAnswer a;
  a.reply = std::make_shared<wire::JobDetail>(std::move(*detail));
  return a;
}

RequestAnswer Broker::change_worker(const wire::ChangeWorker& request, const std::string* user,
                                    bool& changed) {
  const wire::ChangeWorker::Control control = request.control();
  if (control != wire::ChangeWorker::ENABLE && control != wire::ChangeWorker::DRAIN &&
      control != wire::ChangeWorker::DISABLE) {
    return refused(wire::Error::BAD_REQUEST,
                   "say what to do with the worker: enable, drain or "
                   "disable");
  }
  // The worker: by its id, else by its name when exactly one connected worker has it.
  const std::string& wanted = request.worker();
  const std::string shown = protocol::printable(wanted, 80);
  auto found = workers_.end();
  std::vector<std::string> namesakes;
  for (auto it = workers_.begin(); it != workers_.end(); ++it) {
    if (net::peer_label(it->first) == wanted) {
      found = it;
      namesakes.clear();
      break;
    }
    if (it->second.name == wanted) {
      namesakes.push_back(net::peer_label(it->first));
      found = it;
    }
  }
  if (found == workers_.end()) {
    return refused(
        wire::Error::NOT_FOUND,
        fmt::format("no worker '{}' is connected (`rayfarm workers` lists them)", shown));
  }
  if (namesakes.size() > 1) {
    std::string ids;
    for (const auto& n : namesakes) ids += (ids.empty() ? "" : ", ") + n;
    return refused(wire::Error::REFUSED,
                   fmt::format("{} workers are named '{}': give the id of one ({})",
                               namesakes.size(), shown, ids));
  }
  const net::PeerId& peer = found->first;
  Worker& w = found->second;
  // The worker's key is its owner: the client key of the same name, or an admin key, may change
  // it (without keys, every client).
  if (!rights_.may_manage(w.key_name, user)) {
    metrics().refusals.add("worker_forbidden");
    return refused(wire::Error::FORBIDDEN,
                   fmt::format("worker '{}' connected with key '{}': only the client key of that "
                               "name or an admin key (rayfarm-master --admin-clients) may drain, "
                               "disable or enable it",
                               w.name, protocol::printable(w.key_name)));
  }
  if (auto refusal = jobs_.take_change(user ? *user : std::string())) {
    metrics().refusals.add("change_budget");
    return refused(wire::Error::BUSY, *refusal);
  }
  const WorkerControl before = w.control;
  w.control = control == wire::ChangeWorker::ENABLE  ? WorkerControl::kEnabled
              : control == wire::ChangeWorker::DRAIN ? WorkerControl::kDraining
                                                     : WorkerControl::kDisabled;
  const std::string by = JobManager::requester(user ? *user : std::string());
  size_t requeued = 0;
  if (w.control == WorkerControl::kDisabled) {
    // The reply counts the units of the jobs this user sees; the log line all of them.
    for (const std::string& unit : jobs_.units_of(peer)) {
      const std::string* job_owner = jobs_.owner_of(unit.substr(0, unit.find('/')));
      if (job_owner && rights_.may_see(*job_owner, user)) ++requeued;
    }
    const size_t all = jobs_.release_worker(peer, "its worker was disabled by " + by);
    changed = all > 0;  // others may take them
    if (all != requeued) {
      log()->info("{}: {} of its units belong to jobs that {} may not see", worker_label(peer),
                  all - requeued, by);
    }
  }
  if (w.control == WorkerControl::kEnabled && before != WorkerControl::kEnabled) changed = true;
  // Remembered by key and name, so that the worker keeps it when it reconnects.
  const auto remembered = std::make_pair(w.key_name, w.name);
  if (w.control == WorkerControl::kEnabled) {
    controls_.erase(remembered);
  } else if (controls_.size() < kRememberedControls || controls_.count(remembered)) {
    controls_[remembered] = w.control;
  } else {
    log()->warn("{} is {} but not remembered ({} workers are): if it reconnects, it is enabled",
                worker_label(peer), control_verb(control), kRememberedControls);
  }
  log()->info("{} {} by {}{}", worker_label(peer), control_verb(control), by,
              requeued
                  ? fmt::format(": {} unit{} back in the queue", requeued, requeued == 1 ? "" : "s")
                  : std::string());
  auto reply = std::make_shared<wire::ChangeWorkerReply>();
  *reply->mutable_worker() = worker_info(peer, w, user);
  reply->set_units_requeued(static_cast<uint32_t>(requeued));
  reply->set_protocol_version(protocol::kProtocolVersion);
  RequestAnswer a;
  a.reply = std::move(reply);
  return a;
}

}  // namespace rayfarm::master
