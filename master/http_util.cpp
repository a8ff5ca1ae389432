#include "master/http_util.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <fstream>
#include <iterator>
#include <map>
#include <regex>
#include <stdexcept>

#include <google/protobuf/util/json_util.h>

namespace rayfarm::master::http_util {

using nlohmann::json;

namespace {
/// The niceness of the threads that serve HTTP requests.
constexpr int kNice = 10;
}  // namespace

void lower_thread_priority() {
  const id_t self = static_cast<id_t>(::gettid());
  errno = 0;
  const int now = ::getpriority(PRIO_PROCESS, self);
  if (errno != 0) return;
  ::setpriority(PRIO_PROCESS, self, std::min(19, now + kNice));
}

BoundedPool::BoundedPool(size_t threads) {
  for (size_t i = 0; i < threads; ++i) threads_.emplace_back([this] { work(); });
}

void BoundedPool::enqueue(std::function<void()> fn) {
  {
    std::unique_lock lock(mutex_);
    if (queue_.size() < kMaxQueuedConnections) {
      queue_.push_back(std::move(fn));
      ready_.notify_one();
      return;
    }
  }
  fn();
}

void BoundedPool::shutdown() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  ready_.notify_all();
  for (auto& t : threads_) t.join();
}

void BoundedPool::work() {
  lower_thread_priority();
  for (;;) {
    std::function<void()> fn;
    {
      std::unique_lock lock(mutex_);
      ready_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, nothing left
      fn = std::move(queue_.front());
      queue_.pop_front();
    }
    fn();
  }
}

json message_json(const google::protobuf::Message& m) {
  google::protobuf::util::JsonPrintOptions options;
  options.preserve_proto_field_names = true;
  options.always_print_primitive_fields = true;
  std::string text;
  if (!google::protobuf::util::MessageToJsonString(m, &text, options).ok()) {
    throw std::runtime_error("cannot write " + m.GetTypeName() + " as JSON");
  }
  json out = json::parse(text);
  out.erase("protocol_version");
  return out;
}

void send_json(httplib::Response& res, const json& body, int status) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  // Text from peers (names, errors) may hold bytes that are not UTF-8: replaced, not fatal.
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

void send_error(httplib::Response& res, int status, const std::string& error) {
  send_json(res, json{{"error", error}}, status);
}

BearerToken bearer(const httplib::Request& req) {
  const size_t count = req.get_header_value_count("Authorization");
  if (count == 0) return {};
  if (count > 1) {
    // Two credentials: which one a proxy or the master would read is anybody's guess.
    return {"", "the request has " + std::to_string(count) +
                    " Authorization headers: send exactly one, 'Authorization: Bearer TOKEN'"};
  }
  const std::string value = req.get_header_value("Authorization");
  const std::string_view scheme = "bearer";
  const auto lower = [](char c) {
    return static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  };
  size_t at = 0;
  while (at < scheme.size() && at < value.size() && lower(value[at]) == scheme[at]) ++at;
  const size_t token_at = value.find_first_not_of(' ', at);
  if (at != scheme.size() || token_at == at || token_at == std::string::npos) {
    return {"", "malformed Authorization header: send 'Authorization: Bearer TOKEN' with a token "
                "from `rayfarm token`"};
  }
  return {value.substr(token_at), ""};
}

bool plausible_job_id(const std::string& id) {
  static const std::regex pattern("[A-Za-z0-9_-]{1,64}(\\.-?[0-9]{1,19})?");
  return std::regex_match(id, pattern);
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}


void farm_metrics(PrometheusText& text, const FarmSnapshot& snap) {
  // "JOB_RUNNING" -> "running"; every state listed, also at 0.
  const auto label = [](wire::JobState state) {
    std::string name = wire::JobState_Name(state);
    name = name.substr(name.rfind('_') + 1);
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return name;
  };
  std::map<std::string, double> states;
  for (int k = wire::JobState_MIN; k <= wire::JobState_MAX; ++k) {
    if (k != wire::JOB_STATE_UNSPECIFIED && wire::JobState_IsValid(k)) {
      states[label(static_cast<wire::JobState>(k))] = 0;
    }
  }
  double rate = 0, paused = 0;
  for (const auto& st : snap.jobs.jobs()) {
    states[label(st.state())] += 1;
    if (st.state() == wire::JOB_RUNNING) rate += st.samples_per_second();
    if (st.paused()) paused += 1;
  }
  text.family("rayfarm_jobs", "gauge",
              "Jobs (a sequence counts once) by state, as listed by rayfarm list.", "state", states);
  text.gauge("rayfarm_jobs_paused", "Queued or running jobs that are paused.", paused);
  text.gauge("rayfarm_samples_per_second",
             "Pixel samples per second of the running jobs, as their status reports.", rate);
}

}  // namespace rayfarm::master::http_util
