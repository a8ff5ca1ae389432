#pragma once
// The master's HTTP endpoint: the dashboard (a page embedded in the binary, web/), its JSON API
// under /api/ (docs/farm.md, "The dashboard"), and /metrics for Prometheus. It runs on threads of
// its own and sees the farm only through an HttpFeed (http_feed.h): snapshots the reactor
// publishes, and calls the reactor answers between two polls. Reads need no token unless the
// master keeps jobs private; actions need a bearer token (http_tokens.h) whose key may manage the
// job, exactly as on the client socket.
// Bounded: a request's line and headers of at most 64 KiB and 100 header lines, measured before
// they are parsed (http_guard.h, answered 431 beyond), bodies of at most 64 KiB, a fixed pool of threads with a bounded queue of connections
// (beyond it the accepting thread serves one itself, so that the kernel's backlog, not the
// master's memory, takes the rest), short keep-alives, at most HttpFeed::kMaxCalls calls waiting.
// On a loopback endpoint a request must name a loopback host (no DNS rebinding).
#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "master/http_feed.h"
#include "master/http_tokens.h"
#include "master/job_rights.h"

namespace httplib {
class Server;
}

namespace rayfarm::master {

struct HttpOptions {
  /// HOST:PORT ("127.0.0.1:8480", "0.0.0.0:8480", "[::1]:0"); port 0 picks a free one.
  std::string endpoint;
  /// Whether the master checks client keys. Without (rayfarm-master --insecure) the endpoint
  /// must be on loopback, as the master's sockets must.
  bool keys = true;
  /// Who may see and change which job, as on the client socket.
  JobRights rights;
  /// <data>/jobs: where the images, error plots and contact sheets are read from.
  std::filesystem::path jobs_dir;
  /// The name the clients' allow-list lists a token's key under now (http_tokens.h); unset: a
  /// master without keys, whose one nameless key is "".
  HttpTokens::NameOf name_of;
  /// Whether jobs and workers may be read without a token (the default on loopback endpoints);
  /// otherwise only the page itself and /metrics are.
  bool anonymous_read = true;
  /// The master's build, shown on the page.
  std::string build;
  int threads = 16;
};

/// HOST and PORT of "HOST:PORT" ("[::1]:8480" gives "::1"). Throws std::invalid_argument naming
/// --http-endpoint when it is not of that form.
std::pair<std::string, int> parse_http_endpoint(const std::string& endpoint);

class HttpServer {
 public:
  /// Binds and starts serving. Throws std::runtime_error naming the endpoint when it cannot be
  /// bound, or when it is beyond loopback on a master without keys.
  HttpServer(HttpOptions options, HttpFeed& feed, const HttpTokens& tokens);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  int port() const { return port_; }
  /// http://HOST:PORT/
  std::string url() const;

 private:
  HttpOptions options_;
  HttpFeed& feed_;
  const HttpTokens& tokens_;
  std::unique_ptr<httplib::Server> server_;
  std::string host_;
  int port_ = 0;
  bool loopback_ = false;
  std::atomic<bool> listening_ended_{false};
  std::thread thread_;
  // The latest snapshot as JSON, made once for all the requests that read it (pages poll).
  struct SnapshotJson;  // http_server.cpp
  std::mutex json_mutex_;
  std::shared_ptr<const SnapshotJson> json_;
  std::shared_ptr<const SnapshotJson> json_of(const std::shared_ptr<const FarmSnapshot>& snap);

  void routes();
};

}  // namespace rayfarm::master
