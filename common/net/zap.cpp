#include "common/net/zap.h"

#include <iterator>
#include <vector>

#include <zmq_addon.hpp>

#include "common/net/context.h"
#include "common/net/keys.h"
#include "common/net/socket.h"

namespace rayfarm::net {
namespace {

/// How often the handler's thread looks at its stop flag.
constexpr std::chrono::milliseconds kStopCheck{100};

}  // namespace

struct ZapHandler::Impl {
  zmq::socket_t socket;
  ZapPolicy policy;
};

ZapHandler::ZapHandler(ZapPolicy policy) : impl_(std::make_unique<Impl>()) {
  impl_->policy = std::move(policy);
  try {
    impl_->socket = zmq::socket_t(detail::context(), zmq::socket_type::rep);
    impl_->socket.set(zmq::sockopt::linger, 0);
    impl_->socket.bind(kZapEndpoint);
  } catch (const zmq::error_t& e) {
    throw NetError(std::string("cannot bind the ZAP handler at ") + kZapEndpoint + ": " + e.what());
  }
  thread_ = std::thread([this] { serve(); });
}

ZapHandler::~ZapHandler() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

void ZapHandler::serve() {
  zmq::socket_t& socket = impl_->socket;
  while (!stop_.load()) {
    std::vector<zmq::pollitem_t> items{{socket.handle(), 0, ZMQ_POLLIN, 0}};
    try {
      zmq::poll(items, kStopCheck);
    } catch (const zmq::error_t&) {
      continue;  // EINTR
    }
    if (!(items[0].revents & ZMQ_POLLIN)) continue;
    std::vector<zmq::message_t> request;
    try {
      if (!zmq::recv_multipart(socket, std::back_inserter(request), zmq::recv_flags::dontwait))
        continue;
    } catch (const zmq::error_t&) {
      continue;
    }
    // RFC 27: version, request id, domain, address, identity, mechanism, credentials...
    const auto frame = [&](size_t i) {
      return i < request.size() ? request[i].to_string() : std::string();
    };
    std::string status = "400", text = "refused", user;
    ZapRequest r;
    if (request.size() >= 6 && frame(0) == "1.0") {
      r.domain = frame(2);
      r.address = frame(3);
      r.mechanism = frame(5);
      if (r.mechanism == "CURVE" && request.size() >= 7) r.key = z85_of(frame(6));
      try {
        const ZapVerdict verdict = impl_->policy(r);
        if (verdict.admitted) {
          status = "200";
          text = "OK";
          user = verdict.user;
        }
      } catch (const std::exception&) {
        status = "500";
        text = "the authentication policy failed";
      }
    } else {
      status = "500";
      text = "malformed ZAP request";
    }
    ++requests_;
    if (status != "200") ++refusals_;
    // An admitted CURVE peer's key goes with its messages as the property X-Key (ZMTP metadata:
    // a name of 1-byte length, a value of 4-byte big-endian length), beside its User-Id.
    std::string metadata;
    if (status == "200" && !r.key.empty()) {
      const std::string name = kKeyProperty;
      metadata += static_cast<char>(name.size());
      metadata += name;
      const uint32_t n = static_cast<uint32_t>(r.key.size());
      for (int shift = 24; shift >= 0; shift -= 8) metadata += static_cast<char>((n >> shift) & 0xff);
      metadata += r.key;
    }
    const std::vector<std::string> reply{"1.0", frame(1), status, text, user, metadata};
    std::vector<zmq::const_buffer> parts;
    for (const auto& p : reply) parts.push_back(zmq::buffer(p));
    try {
      zmq::send_multipart(socket, parts);
    } catch (const zmq::error_t&) {
      // the requesting session is gone; nothing to answer
    }
  }
  socket.close();
}

AllowListPolicy::AllowListPolicy(std::map<std::string, std::filesystem::path> lists,
                                 std::chrono::milliseconds reload_interval)
    : reload_interval_(reload_interval), loaded_(std::chrono::steady_clock::now()) {
  for (auto& [domain, path] : lists) domains_[domain] = Domain{path, AllowList::load(path), {}};
}

void AllowListPolicy::reload(Decision& out) {
  const auto add = [&out](const std::string& text, bool warning) {
    out.reload_note += (out.reload_note.empty() ? "" : "; ") + text;
    out.reload_warning = out.reload_warning || warning;
  };
  for (auto& [domain, d] : domains_) {
    const std::string list = "the " + domain + " allow-list " + d.path.string();
    std::vector<std::string> problems;
    AllowList fresh;
    try {
      fresh = AllowList::load(d.path, &problems);
    } catch (const KeyError& e) {
      // Nothing of the list could be read (the path is gone or cannot be listed).
      problems = {e.what()};
      if (problems != d.problems) {
        add("cannot read " + list + " again, keeping its " + std::to_string(d.keys.size()) +
                " keys: " + e.what(),
            true);
      }
      d.problems = std::move(problems);
      continue;
    }
    if (!(fresh == d.keys)) {
      add(list + " changed: " + std::to_string(fresh.size()) + " keys (was " +
              std::to_string(d.keys.size()) + ")",
          false);
      d.keys = std::move(fresh);
    }
    if (problems != d.problems) {
      if (problems.empty()) {
        add(list + " is read in full again", false);
      } else {
        std::string text = list + ": skipped what cannot be read (no key of it is admitted): ";
        for (size_t i = 0; i < problems.size(); ++i) text += (i ? "; " : "") + problems[i];
        add(text, true);
      }
    }
    d.problems = std::move(problems);
  }
}

void AllowListPolicy::reload_if_due(Decision& out) {
  const auto now = std::chrono::steady_clock::now();
  if (now - loaded_ >= reload_interval_) {
    reload(out);
    loaded_ = now;
  }
}

AllowListPolicy::Decision AllowListPolicy::decide(const ZapRequest& request) {
  std::lock_guard lock(mutex_);
  Decision out;
  reload_if_due(out);
  if (request.mechanism != "CURVE") {
    out.reason = "it connected without CURVE (" + request.mechanism + ")";
    return out;
  }
  auto it = domains_.find(request.domain);
  if (it == domains_.end()) {
    out.reason = "the socket's ZAP domain '" + request.domain + "' has no allow-list";
    return out;
  }
  if (const std::string* name = it->second.keys.find(request.key)) {
    out.admitted = true;
    out.name = *name;
    return out;
  }
  out.reason = "key " + key_label(request.key) + " is not on the " + request.domain + " allow-list";
  for (const auto& [other, d] : domains_) {
    if (other == request.domain) continue;
    if (const std::string* name = d.keys.find(request.key)) {
      out.reason += " (it is " + other + " key '" + *name + "')";
    }
  }
  return out;
}

AllowListPolicy::Decision AllowListPolicy::admits_key(const std::string& domain,
                                                      const std::string& key) {
  std::lock_guard lock(mutex_);
  Decision out;
  reload_if_due(out);
  auto it = domains_.find(domain);
  const std::string* name = it == domains_.end() ? nullptr : it->second.keys.find(key);
  if (name) {
    out.admitted = true;
    out.name = *name;
  } else {
    out.reason = "key " + key_label(key) + " is not on the " + domain + " allow-list";
  }
  return out;
}

size_t AllowListPolicy::size(const std::string& domain) const {
  std::lock_guard lock(mutex_);
  auto it = domains_.find(domain);
  return it == domains_.end() ? 0 : it->second.keys.size();
}

}  // namespace rayfarm::net
