#pragma once
// What the HTTP endpoint's routes (http_server.cpp) are made of: its thread pool, JSON answers,
// the bearer token of a request, the check of a job id before it becomes a path, and the farm's
// figures for /metrics.
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <google/protobuf/message.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "master/http_feed.h"
#include "master/metrics.h"

namespace rayfarm::master::http_util {

/// Connections queued for the pool at most; beyond, the accepting thread serves one itself.
constexpr size_t kMaxQueuedConnections = 256;

/// Lowers the calling thread's priority (Linux: its niceness, by 10) below the reactor's and the
/// writers': when the cores are short, the page waits, not the farm.
void lower_thread_priority();

/// A fixed pool of threads with a bounded queue of connections. When the queue is full the
/// accepting thread serves the connection itself: it accepts no more meanwhile, and the kernel's
/// backlog holds (or refuses) the rest, rather than the master's memory.
class BoundedPool : public httplib::TaskQueue {
 public:
  explicit BoundedPool(size_t threads);
  void enqueue(std::function<void()> fn) override;
  void shutdown() override;

 private:
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;

  void work();
};

/// A wire message as JSON, with its proto field names and every field (no protocol_version).
nlohmann::json message_json(const google::protobuf::Message& m);
/// Answers `body` (bytes that are not UTF-8 replaced), never cached.
void send_json(httplib::Response& res, const nlohmann::json& body, int status = 200);
/// Answers {"error": error} with `status`.
void send_error(httplib::Response& res, int status, const std::string& error);
/// The token of a request's "Authorization: Bearer TOKEN" (the scheme in any case, as RFC 9110
/// says, then one or more spaces), or why there is none to use.
struct BearerToken {
  std::string token;  ///< "" when the request has no Authorization header
  std::string error;  ///< why the header cannot be used: malformed, or given twice
};
BearerToken bearer(const httplib::Request& req);
/// Job ids are the master's own ("j0007", a sequence's frame "j0007.12"): anything else is
/// refused before it is looked up or joined to a path.
bool plausible_job_id(const std::string& id);
/// A whole file; "" when it cannot be read.
std::string read_file(const std::filesystem::path& path);
/// The jobs by state, the paused ones and the running ones' samples per second.
void farm_metrics(PrometheusText& text, const FarmSnapshot& snap);

}  // namespace rayfarm::master::http_util
