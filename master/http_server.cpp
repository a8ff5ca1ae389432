#include "master/http_server.h"

#include <sys/socket.h>

#include <chrono>
#include <set>
#include <stdexcept>

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "common/limits.h"
#include "common/net/keys.h"
#include "common/util/log.h"
#include "master/http_guard.h"
#include "master/http_util.h"
#include "master/metrics.h"
#include "master/web_assets.h"

namespace rayfarm::master {
namespace {

using nlohmann::json;
using namespace http_util;
using namespace std::chrono_literals;

std::shared_ptr<spdlog::logger> log() { return get_logger("master"); }

constexpr size_t kMaxRequestBytes = 64 * 1024;
/// How long a request waits for the reactor (a snapshot, or a call's answer).
constexpr auto kReactorWait = 5s;

}  // namespace

std::pair<std::string, int> parse_http_endpoint(const std::string& endpoint) {
  const auto bad = [&] {
    return std::invalid_argument("--http-endpoint '" + endpoint +
                                 "' is not HOST:PORT (e.g. 127.0.0.1:8480, 0.0.0.0:8480, "
                                 "[::1]:8480)");
  };
  const size_t colon = endpoint.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == endpoint.size()) throw bad();
  std::string host = endpoint.substr(0, colon);
  if (host.front() == '[') {
    if (host.back() != ']' || host.size() < 3) throw bad();
    host = host.substr(1, host.size() - 2);
  } else if (host.find(':') != std::string::npos) {
    throw bad();
  }
  const std::string port_text = endpoint.substr(colon + 1);
  if (port_text.size() > 5 || port_text.find_first_not_of("0123456789") != std::string::npos) {
    throw bad();
  }
  const int port = std::stoi(port_text);
  if (port > 65535) throw bad();
  return {host, port};
}

HttpServer::HttpServer(HttpOptions options, HttpFeed& feed, const HttpTokens& tokens)
    : options_(std::move(options)), feed_(feed), tokens_(tokens) {
  auto [host, port] = parse_http_endpoint(options_.endpoint);
  host_ = host;
  const std::string as_tcp =
      "tcp://" + (host.find(':') != std::string::npos ? "[" + host + "]" : host) + ":" +
      std::to_string(port);
  if (!options_.keys && !net::is_loopback_endpoint(as_tcp)) {
    throw std::runtime_error(
        "--http-endpoint " + options_.endpoint +
        " is reachable from other machines, and a master without keys (--insecure) has no "
        "tokens to guard its actions: bind it to 127.0.0.1, or give the master its keys");
  }
  server_ = std::make_unique<GuardedHttpServer>();  // heads measured before they are parsed
  const size_t threads = static_cast<size_t>(std::max(1, options_.threads));
  server_->new_task_queue = [threads] { return new BoundedPool(threads); };
  // SO_REUSEADDR only: the library's default adds SO_REUSEPORT, with which a second master would
  // bind the same port and take half of the requests.
  server_->set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  server_->set_payload_max_length(kMaxRequestBytes);
  server_->set_read_timeout(5, 0);
  server_->set_write_timeout(10, 0);
  // A connection holds a thread for its keep-alive: kept short, so that an open page (which polls
  // every second) does not hold one for long.
  server_->set_keep_alive_timeout(2);
  server_->set_keep_alive_max_count(10);
  loopback_ = net::is_loopback_endpoint(as_tcp);
  routes();
  port_ = port == 0 ? server_->bind_to_any_port(host) : (server_->bind_to_port(host, port) ? port : -1);
  if (port_ <= 0) {
    throw std::runtime_error("cannot bind --http-endpoint " + options_.endpoint +
                             ": the address is in use or not this machine's");
  }
  thread_ = std::thread([this] {
    lower_thread_priority();  // below the reactor, as the pool's threads are
    server_->listen_after_bind();
    listening_ended_ = true;
  });
  // stop() does nothing before the server runs: wait until it does (or its listening ended at
  // once), so that a server destroyed at once still stops.
  while (!server_->is_running() && !listening_ended_) std::this_thread::sleep_for(1ms);
  if (!server_->is_running()) {
    if (thread_.joinable()) thread_.join();
    throw std::runtime_error("cannot serve --http-endpoint " + options_.endpoint);
  }
  log()->info("dashboard and metrics on {} ({})", url(),
              options_.keys ? "actions need a token: rayfarm token"
                            : "no keys: any local process may act");
}

HttpServer::~HttpServer() {
  server_->stop();
  if (thread_.joinable()) thread_.join();
}

struct HttpServer::SnapshotJson {
  std::shared_ptr<const FarmSnapshot> snap;
  std::vector<json> jobs;      ///< each job's status, in the snapshot's order
  std::string jobs_anonymous;  ///< all of them with can_manage false, as text
  std::string workers_all;     ///< /api/workers for a reader who sees every job
};

std::shared_ptr<const HttpServer::SnapshotJson> HttpServer::json_of(
    const std::shared_ptr<const FarmSnapshot>& snap) {
  std::lock_guard lock(json_mutex_);
  if (json_ && json_->snap == snap) return json_;
  auto fresh = std::make_shared<SnapshotJson>();
  fresh->snap = snap;
  json anonymous = json::array();
  for (const auto& st : snap->jobs.jobs()) {
    fresh->jobs.push_back(message_json(st));
    json j = fresh->jobs.back();
    j["can_manage"] = false;
    anonymous.push_back(std::move(j));
  }
  fresh->jobs_anonymous = anonymous.dump(-1, ' ', false, json::error_handler_t::replace);
  json workers = message_json(snap->workers);
  if (!workers.contains("workers")) workers["workers"] = json::array();
  for (auto& w : workers["workers"]) w["can_manage"] = false;
  fresh->workers_all = workers.dump(-1, ' ', false, json::error_handler_t::replace);
  json_ = fresh;
  return json_;
}

std::string HttpServer::url() const {
  const std::string host = host_ == "0.0.0.0" || host_.empty() ? "127.0.0.1"
                           : host_ == "::"                     ? "[::1]"
                           : host_.find(':') != std::string::npos ? "[" + host_ + "]"
                                                                  : host_;
  return "http://" + host + ":" + std::to_string(port_) + "/";
}

void HttpServer::routes() {
  httplib::Server& s = *server_;
  s.set_default_headers({{"X-Content-Type-Options", "nosniff"},
                         {"X-Frame-Options", "DENY"},
                         {"Referrer-Policy", "no-referrer"},
                         {"Content-Security-Policy",
                          "default-src 'self'; img-src 'self' data: blob:; style-src 'self'; "
                          "script-src 'self'; connect-src 'self'; frame-ancestors 'none'"}});
  s.set_logger([](const httplib::Request&, const httplib::Response& res) {
    metrics().http_responses.add(std::to_string(res.status));
  });
  s.set_exception_handler([](const httplib::Request& req, httplib::Response& res,
                             std::exception_ptr ep) {
    std::string what = "unknown error";
    try {
      if (ep) std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    log()->error("HTTP {} {}: {}", req.method, req.path, what);
    send_error(res, 500, "the master failed to answer: " + what);
  });
  s.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;
    if (res.status == 404) {
      send_error(res, 404, "no such page: " + req.method + " " + req.path);
    } else if (res.status == 413) {
      send_error(res, 413, "request too large (at most 64 KiB)");
    } else {
      send_error(res, res.status, "HTTP " + std::to_string(res.status));
    }
  });

  // On a loopback endpoint, a request for another host is a page elsewhere that rebound its name
  // to this machine: refused.
  if (loopback_) {
    s.set_pre_routing_handler([](const httplib::Request& req, httplib::Response& res) {
      std::string host = req.get_header_value("Host");
      if (!host.empty() && host.front() == '[') {
        host = host.substr(1, host.find(']') == std::string::npos ? 0 : host.find(']') - 1);
      } else if (const size_t colon = host.rfind(':'); colon != std::string::npos) {
        host = host.substr(0, colon);
      }
      for (char& c : host) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      // No Host at all (HTTP/1.0 tools) is no browser being rebound.
      // 127.x.x.x written as numbers ("127.evil.example" is a name that could be rebound).
      const bool local = host.empty() || host == "localhost" || host == "::1" ||
                         (host.rfind("127.", 0) == 0 &&
                          host.find_first_not_of("0123456789.") == std::string::npos);
      if (local) return httplib::Server::HandlerResponse::Unhandled;
      send_error(res, 403, "this endpoint serves loopback only: ask for http://127.0.0.1:PORT/ "
                           "or http://localhost:PORT/");
      return httplib::Server::HandlerResponse::Handled;
    });
  }

  // Who asks: nullopt (and the response set to 401) for a token that is not valid.
  const HttpTokens::NameOf name_of =
      options_.name_of ? options_.name_of : [](const std::string& key) -> std::optional<std::string> {
        if (key.empty()) return std::string();
        return std::nullopt;
      };
  // A 401, counted: nullopt for the handlers to return.
  auto unauthorized = [](httplib::Response& res, const char* why) -> std::optional<HttpUser> {
    metrics().refusals.add("http_token");
    send_error(res, 401, why);
    return std::nullopt;
  };
  auto user_of = [this, name_of, unauthorized](const httplib::Request& req,
                                              httplib::Response& res) -> std::optional<HttpUser> {
    const BearerToken token = bearer(req);
    if (!token.error.empty()) return unauthorized(res, token.error.c_str());
    if (token.token.empty()) return HttpUser{};
    const auto name = tokens_.verify(token.token, name_of);
    if (!name) {
      return unauthorized(res,
                          "this token is not valid here: not issued by this master (or its secret "
                          "was renewed), or its client key is no longer on the allow-list or was "
                          "replaced; get one with `rayfarm token`");
    }
    return HttpUser{true, *name};
  };
  // A reader: a token's user, or nobody where anonymous reads are allowed.
  auto reader_of = [this, user_of, unauthorized](
                       const httplib::Request& req, httplib::Response& res) -> std::optional<HttpUser> {
    auto user = user_of(req, res);
    if (user && !user->authenticated && !options_.anonymous_read) {
      return unauthorized(res,
                          "this master's HTTP endpoint is reachable from other machines: reading "
                          "needs a token too (rayfarm token; the page asks under Sign in), unless "
                          "the master runs with --http-anonymous-read");
    }
    return user;
  };
  // The client socket's rules (job_rights.h), for a token's key or for nobody.
  auto key = [](const HttpUser& u) { return u.authenticated ? &u.key_name : nullptr; };
  auto is_admin = [this, key](const HttpUser& u) { return options_.rights.is_admin(key(u)); };
  auto may_manage = [this, key](const std::string& owner, const HttpUser& u) {
    return options_.rights.may_manage(owner, key(u));
  };
  auto may_see = [this, key](const std::string& owner, const HttpUser& u) {
    return options_.rights.may_see(owner, key(u));
  };
  auto snapshot = [this](httplib::Response& res) -> std::shared_ptr<const FarmSnapshot> {
    auto snap = feed_.snapshot(std::chrono::duration_cast<std::chrono::milliseconds>(kReactorWait));
    if (!snap) send_error(res, 503, "the master has not published its state yet; try again");
    return snap;
  };

  auto asset = [&s](const std::string& path, std::string_view body, const char* type) {
    s.Get(path, [body, type](const httplib::Request&, httplib::Response& res) {
      res.set_header("Cache-Control", "no-cache");
      res.set_content(body.data(), body.size(), type);
    });
  };
  asset("/", web::kIndexHtml, "text/html; charset=utf-8");
  asset("/dashboard.js", web::kDashboardJs, "text/javascript; charset=utf-8");
  asset("/dashboard.css", web::kDashboardCss, "text/css; charset=utf-8");
  asset("/favicon.svg", web::kFaviconSvg, "image/svg+xml");

  s.Get("/api/session", [=, this](const httplib::Request& req, httplib::Response& res) {
    const auto user = user_of(req, res);
    if (!user) return;
    send_json(res, json{{"authenticated", user->authenticated},
                        {"key", user->key_name},
                        {"admin", is_admin(*user)},
                        {"keys", options_.keys},
                        {"private_jobs", options_.rights.private_jobs},
                        {"anonymous_read", options_.anonymous_read},
                        {"build", options_.build}});
  });

  s.Get("/api/jobs", [=, this](const httplib::Request& req, httplib::Response& res) {
    const auto user = reader_of(req, res);
    if (!user) return;
    const auto snap = snapshot(res);
    if (!snap) return;
    const auto cached = json_of(snap);
    const double age =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - snap->taken).count();
    if (!user->authenticated && !options_.rights.private_jobs) {
      // Every job, none of them the reader's: the same text for every such reader.
      res.set_header("Cache-Control", "no-store");
      res.set_content(fmt::format(R"({{"age_seconds":{},"jobs":{},"workers_total":{}}})", age,
                                  cached->jobs_anonymous, snap->workers.workers_size()),
                      "application/json");
      return;
    }
    json jobs = json::array();
    for (int i = 0; i < snap->jobs.jobs_size(); ++i) {
      const auto& st = snap->jobs.jobs(i);
      if (!may_see(st.owner(), *user)) continue;
      json j = cached->jobs[static_cast<size_t>(i)];
      j["can_manage"] = may_manage(st.owner(), *user);
      jobs.push_back(std::move(j));
    }
    send_json(res, json{{"jobs", std::move(jobs)},
                        {"workers_total", snap->workers.workers_size()},
                        {"age_seconds", age}});
  });

  s.Get("/api/workers", [=, this](const httplib::Request& req, httplib::Response& res) {
    const auto user = reader_of(req, res);
    if (!user) return;
    const auto snap = snapshot(res);
    if (!snap) return;
    if (!user->authenticated && !options_.rights.private_jobs) {
      // Every unit shown, no worker this reader may change: the same text for every such reader.
      res.set_header("Cache-Control", "no-store");
      res.set_content(json_of(snap)->workers_all, "application/json");
      return;
    }
    // Which workers this user may drain, disable or enable: the worker's key's own, or an admin.
    auto with_rights = [&](json out) {
      for (auto& w : out["workers"]) {
        w["can_manage"] = may_manage(w.value("key_name", std::string()), *user);
      }
      return out;
    };
    if (!options_.rights.private_jobs || is_admin(*user)) {
      send_json(res, with_rights(json::parse(json_of(snap)->workers_all)));
      return;
    }
    // A worker's units name their jobs: only those this user may see are shown.
    std::set<std::string> visible;
    for (const auto& st : snap->jobs.jobs()) {
      if (may_see(st.owner(), *user)) visible.insert(st.job_id());
    }
    wire::WorkerList workers = snap->workers;
    for (auto& w : *workers.mutable_workers()) {
      auto* units = w.mutable_units();
      for (int i = units->size() - 1; i >= 0; --i) {
        const std::string& unit = units->Get(i);
        const std::string job = unit.substr(0, unit.find('/'));
        if (!visible.count(job.substr(0, job.find('.')))) units->DeleteSubrange(i, 1);
      }
    }
    json out = message_json(workers);
    if (!out.contains("workers")) out["workers"] = json::array();
    send_json(res, with_rights(std::move(out)));
  });

  // A call for the reactor, answered as JSON.
  auto call = [this](HttpCall c, httplib::Response& res) {
    auto answer = feed_.call(std::move(c));
    if (!answer) {
      send_error(res, 503, "the master has too many requests waiting; try again in a moment");
      return;
    }
    if (answer->wait_for(kReactorWait) != std::future_status::ready) {
      send_error(res, 503, "the master did not answer within 5 s; try again");
      return;
    }
    HttpAnswer a = answer->get();
    if (a.status / 100 != 2 || !a.message) {
      send_error(res, a.status, a.error);
      return;
    }
    send_json(res, message_json(*a.message), a.status);
  };

  s.Get(R"(/api/jobs/([^/]+))", [=](const httplib::Request& req, httplib::Response& res) {
    const auto user = reader_of(req, res);
    if (!user) return;
    const std::string id = req.matches[1];
    if (!plausible_job_id(id)) return send_error(res, 404, "unknown job '" + id.substr(0, 80) + "'");
    call(HttpCall{HttpCall::Kind::kStatus, id, *user, 0}, res);
  });
  // Its units, who rendered them and its log: the job view's.
  s.Get(R"(/api/jobs/([^/]+)/detail)", [=](const httplib::Request& req, httplib::Response& res) {
    const auto user = reader_of(req, res);
    if (!user) return;
    const std::string id = req.matches[1];
    if (!plausible_job_id(id))
      return send_error(res, 404, "unknown job '" + id.substr(0, 80) + "'");
    call(HttpCall{HttpCall::Kind::kDetail, id, *user, 0}, res);
  });

  s.Get(R"(/api/jobs/([^/]+)/(image\.png|error\.png|error\.csv|contact\.png))",
        [=, this](const httplib::Request& req, httplib::Response& res) {
          const auto user = reader_of(req, res);
          if (!user) return;
          const std::string id = req.matches[1];
          const std::string file = req.matches[2];
          const auto snap = snapshot(res);
          if (!snap) return;
          // The job, or the sequence a frame's job belongs to, must be one this user sees.
          if (!plausible_job_id(id)) return send_error(res, 404, "unknown job");
          const std::string listed = id.substr(0, id.find('.'));
          const bool frame = listed != id;
          bool visible = false;
          for (const auto& st : snap->jobs.jobs()) {
            if (st.job_id() != listed) continue;
            visible = may_see(st.owner(), *user) && (!frame || st.frames_total() > 0);
            break;
          }
          if (!visible) return send_error(res, 404, "unknown job '" + id + "'");
          const std::string body = read_file(options_.jobs_dir / id / file);
          if (body.empty()) {
            return send_error(res, 404, "job " + id + " has no " + file + " yet");
          }
          res.set_header("Cache-Control", "no-store");
          res.set_content(body, file.ends_with(".csv") ? "text/csv" : "image/png");
        });

  auto action = [=](HttpCall::Kind kind) {
    return [=](const httplib::Request& req, httplib::Response& res) {
      const auto user = user_of(req, res);
      if (!user) return;
      if (!user->authenticated) {
        unauthorized(res, "this needs a token: send 'Authorization: Bearer TOKEN' with a token "
                          "from `rayfarm token` (the page asks for one under Sign in)");
        return;
      }
      const std::string id = req.matches[1];
      const bool worker = kind == HttpCall::Kind::kDrainWorker ||
                          kind == HttpCall::Kind::kDisableWorker ||
                          kind == HttpCall::Kind::kEnableWorker;
      if (!plausible_job_id(id))
        return send_error(res, 404, worker ? "unknown worker" : "unknown job");
      HttpCall c{kind, id, *user, 0};
      if (kind == HttpCall::Kind::kPriority) {
        std::optional<long long> p;
        if (req.has_param("priority")) {
          try {
            size_t used = 0;
            const std::string text = req.get_param_value("priority");
            p = std::stoll(text, &used);
            if (used != text.size()) p.reset();
          } catch (const std::exception&) {
          }
        } else if (!req.body.empty()) {
          const json body = json::parse(req.body, nullptr, /*allow_exceptions=*/false);
          if (body.is_object() && body.contains("priority") &&
              body["priority"].is_number_integer() &&
              (!body["priority"].is_number_unsigned() ||
               body["priority"].get<unsigned long long>() <= 1000000ULL)) {
            p = body["priority"].get<long long>();
          }
        }
        if (!p) {
          return send_error(res, 400,
                            "give the priority as ?priority=P or a JSON body {\"priority\": P}, "
                            "an integer from " + std::to_string(kMinPriority) + " to " +
                                std::to_string(kMaxPriority));
        }
        if (*p < kMinPriority || *p > kMaxPriority) {
          return send_error(res, 400,
                            "priority " + std::to_string(*p) + " is out of range (" +
                                std::to_string(kMinPriority) + " to " +
                                std::to_string(kMaxPriority) + ")");
        }
        c.priority = static_cast<int32_t>(*p);
      }
      call(std::move(c), res);
    };
  };
  s.Post(R"(/api/jobs/([^/]+)/cancel)", action(HttpCall::Kind::kCancel));
  s.Post(R"(/api/jobs/([^/]+)/pause)", action(HttpCall::Kind::kPause));
  s.Post(R"(/api/jobs/([^/]+)/resume)", action(HttpCall::Kind::kResume));
  s.Post(R"(/api/jobs/([^/]+)/priority)", action(HttpCall::Kind::kPriority));
  s.Post(R"(/api/jobs/([^/]+)/retry)", action(HttpCall::Kind::kRetry));
  s.Post(R"(/api/jobs/([^/]+)/remove)", action(HttpCall::Kind::kRemove));
  s.Post(R"(/api/workers/([^/]+)/drain)", action(HttpCall::Kind::kDrainWorker));
  s.Post(R"(/api/workers/([^/]+)/disable)", action(HttpCall::Kind::kDisableWorker));
  s.Post(R"(/api/workers/([^/]+)/enable)", action(HttpCall::Kind::kEnableWorker));

  s.Get("/metrics", [=, this](const httplib::Request&, httplib::Response& res) {
    PrometheusText text;
    text.metrics(metrics());
    if (const auto snap = feed_.snapshot(std::chrono::duration_cast<std::chrono::milliseconds>(
            kReactorWait))) {
      farm_metrics(text, *snap);
    }
    res.set_content(text.text(), "text/plain; version=0.0.4; charset=utf-8");
  });
}

}  // namespace rayfarm::master
