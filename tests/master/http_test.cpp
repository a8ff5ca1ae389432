// The master's HTTP endpoint (http_server.h) and what it is made of: the Prometheus text format,
// tokens, the feed between the reactor and the HTTP threads, and a broker in one process with
// CURVE keys whose dashboard API gives each token exactly its key's rights, and nothing to a
// missing, malformed, forged or revoked token.
#include <gtest/gtest.h>
#include <httplib.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstring>
#include <fstream>

#include <nlohmann/json.hpp>
#include <thread>

#include "common/protocol/codec.h"
#include "master/broker.h"
#include "master/http_feed.h"
#include "master/http_guard.h"
#include "master/http_server.h"
#include "master/http_tokens.h"
#include "master/metrics.h"
#include "tests/master/broker_peer.h"
#include "tests/master/job_requests.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;
using std::chrono::milliseconds;
using testing::TempDir;

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(PrometheusTextTest, HistogramBucketsAreCumulativeAndFamiliesEscaped) {
  Histogram h({0.1, 1.0});
  h.observe(0.05);
  h.observe(0.5);
  h.observe(0.5);
  h.observe(7.0);
  h.observe(std::nan(""));  // ignored
  PrometheusText text;
  text.histogram("x_seconds", "An example.", h);
  text.family("y_total", "counter", "Another.", "reason", {{"a\"b\\c\nd", 2.5}});
  const std::string t = text.text();
  EXPECT_TRUE(contains(t, "# TYPE x_seconds histogram\n")) << t;
  EXPECT_TRUE(contains(t, "x_seconds_bucket{le=\"0.1\"} 1\n")) << t;
  EXPECT_TRUE(contains(t, "x_seconds_bucket{le=\"1\"} 3\n")) << t;
  EXPECT_TRUE(contains(t, "x_seconds_bucket{le=\"+Inf\"} 4\n")) << t;
  EXPECT_TRUE(contains(t, "x_seconds_sum 8.05\n")) << t;
  EXPECT_TRUE(contains(t, "x_seconds_count 4\n")) << t;
  EXPECT_TRUE(contains(t, "y_total{reason=\"a\\\"b\\\\c\\nd\"} 2.5\n")) << t;
}

TEST(HttpTokensTest, VerifiesItsOwnTokensForTheSameKeyOnlyAndKeepsItsSecret) {
  TempDir dir;
  const HttpTokens tokens(dir.path());
  // Two keys of alice (a laptop's and a desktop's), one of bob; "" for a master without keys.
  std::map<std::string, std::string> list{
      {"KEY-LAPTOP", "alice"}, {"KEY-DESKTOP", "alice"}, {"KEY-B", "bob"}, {"", ""}};
  const HttpTokens::NameOf name_of = [&](const std::string& key) -> std::optional<std::string> {
    auto it = list.find(key);
    if (it == list.end()) return std::nullopt;
    return it->second;
  };
  const std::string t = tokens.issue("alice", "KEY-LAPTOP");
  const std::string desktop = tokens.issue("alice", "KEY-DESKTOP");
  EXPECT_NE(t, desktop);
  EXPECT_EQ(tokens.verify(t, name_of), "alice");
  EXPECT_EQ(tokens.verify(tokens.issue("", ""), name_of), "");  // a master without keys
  // Tampered: another name with alice's MAC, a flipped MAC digit, bob's key in alice's token,
  // garbage, empty.
  std::string forged = t;
  forged.replace(5, 10, "626f62");  // "bob"
  EXPECT_FALSE(tokens.verify(forged, name_of));
  std::string flipped = t;
  flipped.back() = flipped.back() == '0' ? '1' : '0';
  EXPECT_FALSE(tokens.verify(flipped, name_of));
  const std::string bobs = tokens.issue("bob", "KEY-B");
  const std::string swapped = t.substr(0, t.find('.', 5) + 1) +
                              bobs.substr(bobs.find('.', 5) + 1, bobs.rfind('.') - bobs.find('.', 5) - 1) +
                              t.substr(t.rfind('.'));
  EXPECT_FALSE(tokens.verify(swapped, name_of));
  EXPECT_FALSE(tokens.verify("rft1.zz.00.00", name_of));
  EXPECT_FALSE(tokens.verify("", name_of));
  EXPECT_FALSE(tokens.verify(std::string(100000, 'a'), name_of));
  // A key taken off the list takes its token with it, and only its own: the other key of the
  // same name keeps its token; a key listed under another name loses it too.
  list.erase("KEY-LAPTOP");
  EXPECT_FALSE(tokens.verify(t, name_of));
  EXPECT_EQ(tokens.verify(desktop, name_of), "alice");
  list["KEY-LAPTOP"] = "mallory";
  EXPECT_FALSE(tokens.verify(t, name_of));
  list["KEY-LAPTOP"] = "alice";
  // The secret survives a restart, is private to the user, and another master's differs.
  EXPECT_EQ(HttpTokens(dir.path()).verify(t, name_of), "alice");
  struct stat st {};
  ASSERT_EQ(::stat((dir.path() / HttpTokens::kSecretFile).c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  TempDir other;
  EXPECT_FALSE(HttpTokens(other.path()).verify(t, name_of));
  // A secret file that is not one is named, not used.
  dir.write(HttpTokens::kSecretFile, "short");
  try {
    HttpTokens broken(dir.path());
    FAIL() << "a 5-byte secret was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_TRUE(contains(e.what(), HttpTokens::kSecretFile)) << e.what();
  }
}

TEST(HttpEndpointTest, ParsesHostAndPortAndNamesTheOptionWhenItCannot) {
  EXPECT_EQ(parse_http_endpoint("127.0.0.1:8480"), (std::pair<std::string, int>{"127.0.0.1", 8480}));
  EXPECT_EQ(parse_http_endpoint("[::1]:0"), (std::pair<std::string, int>{"::1", 0}));
  for (const char* bad : {"8480", "127.0.0.1", ":80", "host:", "host:99999", "::1:80", "h:8x"}) {
    try {
      parse_http_endpoint(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_TRUE(contains(e.what(), "--http-endpoint")) << e.what();
    }
  }
}

TEST(HttpFeedTest, BoundsTheCallsThatWaitForTheReactor) {
  HttpFeed feed;
  std::vector<std::future<HttpAnswer>> waiting;
  for (size_t i = 0; i < HttpFeed::kMaxCalls; ++i) {
    auto f = feed.call(HttpCall{});
    ASSERT_TRUE(f);
    waiting.push_back(std::move(*f));
  }
  EXPECT_FALSE(feed.call(HttpCall{}));  // the reactor is behind: refused, not queued
  EXPECT_EQ(feed.take_calls().size(), HttpFeed::kMaxCalls);
  EXPECT_TRUE(feed.call(HttpCall{}));
  // Nobody looked: no snapshot is due; once someone looks, one is.
  const auto now = HttpFeed::Clock::now();
  EXPECT_FALSE(feed.snapshot_due(now));
  EXPECT_EQ(feed.snapshot(milliseconds{0}), nullptr);
  EXPECT_TRUE(feed.snapshot_due(HttpFeed::Clock::now()));
}

TEST(HttpGuardTest, MeasuresARequestHeadAsTheLibraryReadsIt) {
  using V = HeadScan::Verdict;
  const std::string get = "GET / HTTP/1.1\r\nHost: x\r\n\r\n";
  EXPECT_EQ(scan_request_head(get).verdict, V::kComplete);
  EXPECT_EQ(scan_request_head(get).bytes, get.size());
  // What follows the head (a body, the next request) is not part of it.
  EXPECT_EQ(scan_request_head(get + "GET /x HTTP/1.1\r\n").bytes, get.size());
  for (size_t cut = 0; cut < get.size(); ++cut) {
    EXPECT_EQ(scan_request_head(get.substr(0, cut)).verdict, V::kIncomplete) << cut;
  }
  // Lines ended by a bare LF are header lines the library skips: they do not end the head, but
  // count; an empty CRLF line after one does end it.
  EXPECT_EQ(scan_request_head("GET / HTTP/1.1\r\nA: b\n\n").verdict, V::kIncomplete);
  EXPECT_EQ(scan_request_head("GET / HTTP/1.1\r\nA: b\n\r\n").verdict, V::kComplete);
  // The bounds: bytes before the end of the head, and header lines.
  std::string many = "GET / HTTP/1.1\r\n";
  for (size_t i = 0; i < kMaxHeaderLines; ++i) many += "A: b\r\n";
  EXPECT_EQ(scan_request_head(many + "\r\n").verdict, V::kComplete);
  EXPECT_EQ(scan_request_head(many + "A: b\r\n\r\n").verdict, V::kTooManyFields);
  EXPECT_EQ(scan_request_head(many + "A: b\r\n").verdict, V::kTooManyFields);  // not waited for
  const std::string big = "GET / HTTP/1.1\r\nA: " + std::string(kMaxHeadBytes, 'x');
  EXPECT_EQ(scan_request_head(big).verdict, V::kTooLarge);
  EXPECT_EQ(scan_request_head(big + "\r\n\r\n").verdict, V::kTooLarge);
  EXPECT_EQ(scan_request_head(std::string(kMaxHeadBytes - 1, 'x')).verdict, V::kIncomplete);
  const std::string just = "GET / HTTP/1.1\r\nA: " + std::string(kMaxHeadBytes - 24, 'x') +
                           "\r\n\r\n";
  ASSERT_LE(just.size(), kMaxHeadBytes);
  EXPECT_EQ(scan_request_head(just).verdict, V::kComplete);
}

/// The process's peak resident memory (VmHWM) in bytes; reset_peak() starts it afresh.
uint64_t peak_rss() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  }
  return 0;
}
bool reset_peak() { return static_cast<bool>(std::ofstream("/proc/self/clear_refs") << "5"); }

/// A connection to 127.0.0.1:`port` that sends `request` from a thread of its own (the server
/// may answer and close before it is all sent) and returns the status line of the answer.
std::string raw_exchange(int port, const std::string& request) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
    ::close(fd);
    return "cannot connect";
  }
  timeval timeout{20, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof(timeout));
  std::thread sender([&] {
    size_t sent = 0;
    while (sent < request.size()) {
      const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) break;
      sent += static_cast<size_t>(n);
    }
  });
  std::string answer;
  char buf[4096];
  while (answer.find("\r\n") == std::string::npos) {
    const ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
    if (n <= 0) break;
    answer.append(buf, static_cast<size_t>(n));
  }
  ::shutdown(fd, SHUT_RDWR);
  sender.join();
  ::close(fd);
  return answer.substr(0, answer.find("\r\n"));
}

TEST(HttpServerTest, AMasterWithoutKeysServesHttpOnLoopbackOnly) {
  TempDir dir;
  HttpFeed feed;
  HttpTokens tokens(dir.path());
  HttpOptions o;
  o.keys = false;
  o.endpoint = "0.0.0.0:0";
  try {
    HttpServer server(o, feed, tokens);
    FAIL() << "a master without keys served HTTP beyond loopback";
  } catch (const std::runtime_error& e) {
    EXPECT_TRUE(contains(e.what(), "--http-endpoint 0.0.0.0:0")) << e.what();
  }
  o.endpoint = "127.0.0.1:0";
  HttpServer server(o, feed, tokens);
  EXPECT_GT(server.port(), 0);
  // The port is taken now: a second server names the endpoint.
  o.endpoint = "127.0.0.1:" + std::to_string(server.port());
  try {
    HttpServer second(o, feed, tokens);
    FAIL() << "two servers bound one port";
  } catch (const std::runtime_error& e) {
    EXPECT_TRUE(contains(e.what(), o.endpoint)) << e.what();
  }
}

/// A broker with CURVE keys in this process: clients "owner", "other" and the admin "boss".
class BrokerHttpTest : public ::testing::Test {
 protected:
  TempDir dir;
  net::KeyPair master_keys = net::generate_key_pair();
  std::map<std::string, net::KeyPair> clients{{"owner", net::generate_key_pair()},
                                              {"other", net::generate_key_pair()},
                                              {"boss", net::generate_key_pair()}};
  net::KeyPair worker_keys = net::generate_key_pair();  // the workers' key "w1"
  std::unique_ptr<Broker> broker;
  std::atomic<bool> stop{false};
  std::thread reactor;

  /// The master's options: keys and allow-lists (written once), HTTP on loopback.
  MasterOptions options(bool private_jobs) {
    if (!fs::exists(dir.path() / "clients")) {
      net::write_key_pair(dir.path() / "workers", "w1", worker_keys);
      for (const auto& [name, keys] : clients) {
        net::write_key_pair(dir.path() / "clients", name, keys);
        // Only the public halves on the allow-list.
        fs::remove(dir.path() / "clients" / (name + ".key_secret"));
      }
    }
    MasterOptions o;
    o.worker_endpoint = "tcp://127.0.0.1:0";
    o.client_endpoint = "tcp://127.0.0.1:0";
    o.http_endpoint = "127.0.0.1:0";
    o.data_dir = dir.path() / "data";
    o.security.key = master_keys;
    o.security.worker_keys = dir.path() / "workers";
    o.security.client_keys = dir.path() / "clients";
    o.security.admin_clients = {"boss"};
    o.security.private_jobs = private_jobs;
    return o;
  }
  void start(bool private_jobs) { start(options(private_jobs)); }
  void start(const MasterOptions& o) {
    broker = std::make_unique<Broker>(o);
    reactor = std::thread([this] { broker->run(stop); });
  }
  void halt() {
    stop = true;
    if (reactor.joinable()) reactor.join();
    broker.reset();
    stop = false;
  }
  void TearDown() override { halt(); }

  std::unique_ptr<net::Dealer> client(const std::string& name) {
    const net::KeyPair& k = clients.at(name);
    return std::make_unique<net::Dealer>(broker->client_endpoint(), net::kDefaultMaxMessageBytes,
                                         net::Curve{k.public_key, k.secret_key,
                                                    master_keys.public_key, ""});
  }
  std::string token(const std::string& name) {
    auto c = client(name);
    c->send(protocol::encode(wire::TokenRequest{}));
    auto reply = test_peer::next(*c);
    EXPECT_TRUE(reply && reply->as<wire::TokenReply>());
    EXPECT_EQ(reply->as<wire::TokenReply>()->key_name(), name);
    return reply->as<wire::TokenReply>()->token();
  }
  std::string submit(const std::string& name) {
    auto c = client(name);
    c->send(protocol::encode(test_jobs::furnace_job(64, 16, 8)));
    auto reply = test_peer::next(*c);
    EXPECT_TRUE(reply && reply->as<wire::SubmitReply>());
    EXPECT_TRUE(reply->as<wire::SubmitReply>()->error().empty())
        << reply->as<wire::SubmitReply>()->error();
    return reply->as<wire::SubmitReply>()->job_id();
  }
  httplib::Client http() {
    httplib::Client c(broker->http_url().substr(0, broker->http_url().size() - 1));
    c.set_read_timeout(10, 0);
    return c;
  }
  static httplib::Headers bearer(const std::string& token) {
    return {{"Authorization", "Bearer " + token}};
  }
  /// POST `path` as `token`'s key: the status and the JSON body.
  std::pair<int, json> post(const std::string& path, const std::string& token,
                            const std::string& body = "{}") {
    auto c = http();
    auto res = token.empty() ? c.Post(path, body, "application/json")
                             : c.Post(path, bearer(token), body, "application/json");
    EXPECT_TRUE(res) << path;
    if (!res) return {0, {}};
    return {res->status, json::parse(res->body, nullptr, false)};
  }
  std::pair<int, json> get(const std::string& path, const std::string& token = {}) {
    auto c = http();
    auto res = token.empty() ? c.Get(path) : c.Get(path, bearer(token));
    EXPECT_TRUE(res) << path;
    if (!res) return {0, {}};
    return {res->status, json::parse(res->body, nullptr, false)};
  }
};

TEST_F(BrokerHttpTest, ATokenCarriesExactlyItsKeysRights) {
  start(/*private_jobs=*/false);
  ASSERT_FALSE(broker->http_url().empty());
  const std::string id = submit("owner");  // no workers: it stays queued
  const std::string owner = token("owner"), other = token("other"), boss = token("boss");
  EXPECT_NE(owner, other);

  // Anyone may look; nobody without a token may act.
  auto [status, list] = get("/api/jobs");
  ASSERT_EQ(status, 200) << list.dump();
  ASSERT_EQ(list["jobs"].size(), 1u);
  EXPECT_EQ(list["jobs"][0]["job_id"], id);
  EXPECT_EQ(list["jobs"][0]["owner"], "owner");
  EXPECT_EQ(list["jobs"][0]["can_manage"], false);
  EXPECT_EQ(get("/api/jobs", owner).second["jobs"][0]["can_manage"], true);
  EXPECT_EQ(post("/api/jobs/" + id + "/pause", "").first, 401);
  // Malformed and forged tokens are refused even for reading.
  {
    auto c = http();
    auto res = c.Get("/api/jobs", {{"Authorization", "Basic b3duZXI6"}});
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 401);
  }
  std::string forged = owner;
  forged.back() = forged.back() == 'a' ? 'b' : 'a';
  EXPECT_EQ(post("/api/jobs/" + id + "/pause", forged).first, 401);
  // Another key may not; the owner and the admin may.
  auto [refused, why] = post("/api/jobs/" + id + "/pause", other);
  EXPECT_EQ(refused, 403);
  EXPECT_TRUE(contains(why["error"].get<std::string>(), "belongs to key 'owner'")) << why.dump();
  auto [paused, reply] = post("/api/jobs/" + id + "/pause", owner);
  EXPECT_EQ(paused, 200) << reply.dump();
  EXPECT_EQ(reply["paused"], true);
  EXPECT_EQ(get("/api/jobs/" + id).second["paused"], true);
  // Priorities: above --max-client-priority (0) only for the admin; out of range for nobody.
  EXPECT_EQ(post("/api/jobs/" + id + "/priority", owner, R"({"priority": 5})").first, 403);
  EXPECT_EQ(post("/api/jobs/" + id + "/priority", boss, R"({"priority": 5})").first, 200);
  EXPECT_EQ(post("/api/jobs/" + id + "/priority", boss, R"({"priority": 101})").first, 400);
  EXPECT_EQ(post("/api/jobs/" + id + "/priority", boss, R"({"priority": "high"})").first, 400);
  EXPECT_EQ(post("/api/jobs/" + id + "/resume", boss).first, 200);
  EXPECT_EQ(post("/api/jobs/j9999/cancel", owner).first, 404);
  EXPECT_EQ(post("/api/jobs/" + id + "/cancel", other).first, 403);
  auto [cancelled, c] = post("/api/jobs/" + id + "/cancel", owner);
  EXPECT_EQ(cancelled, 200) << c.dump();
  EXPECT_EQ(c["state"], "JOB_CANCELLED");
  EXPECT_EQ(post("/api/jobs/" + id + "/pause", owner).first, 409);  // over: named, not changed

  // A key taken off the allow-list loses its token's rights (the list is read again each second),
  // and a connection it opened before gets no new token.
  auto still_open = client("other");
  still_open->send(protocol::encode(wire::ListJobs{}));
  ASSERT_TRUE(test_peer::next(*still_open));
  fs::remove(dir.path() / "clients" / "other.key");
  int revoked = 0;
  for (int i = 0; i < 50 && revoked != 401; ++i) {
    revoked = get("/api/session", other).first;
    if (revoked != 401) std::this_thread::sleep_for(milliseconds{100});
  }
  EXPECT_EQ(revoked, 401);
  EXPECT_EQ(get("/api/session", owner).second["key"], "owner");
  still_open->send(protocol::encode(wire::TokenRequest{}));
  auto refused_token = test_peer::next(*still_open);
  ASSERT_TRUE(refused_token && refused_token->as<wire::Error>()) << refused_token->type;
  EXPECT_EQ(refused_token->as<wire::Error>()->code(), wire::Error::FORBIDDEN);

  // A page elsewhere that rebinds its name to this machine is refused.
  {
    auto h = http();
    for (const char* host : {"attacker.example:8480", "127.attacker.example"}) {
      auto res = h.Get("/api/jobs", {{"Host", host}});
      ASSERT_TRUE(res);
      EXPECT_EQ(res->status, 403) << host;
    }
    auto res = h.Get("/api/jobs", {{"Host", "localhost:8480"}});
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200);
  }

  // Bad requests: unknown routes, ids that are paths, oversized bodies.
  EXPECT_EQ(get("/api/nothing").first, 404);
  EXPECT_EQ(get("/api/jobs/..%2F..%2Fetc/image.png").first, 404);
  EXPECT_EQ(get("/api/jobs/" + id + "/job.json").first, 404);
  EXPECT_EQ(post("/api/jobs/" + id + "/priority", owner, std::string(200 * 1024, ' ')).first, 413);

  // The metrics count what happened.
  auto c2 = http();
  auto m = c2.Get("/metrics");
  ASSERT_TRUE(m);
  EXPECT_EQ(m->status, 200);
  EXPECT_TRUE(contains(m->body, "rayfarm_jobs{state=\"cancelled\"} 1\n")) << m->body;
  EXPECT_TRUE(contains(m->body, "rayfarm_refusals_total{reason=\"http_token\"}")) << m->body;
  EXPECT_TRUE(contains(m->body, "rayfarm_refusals_total{reason=\"http_forbidden\"}")) << m->body;
  EXPECT_TRUE(contains(m->body, "# TYPE rayfarm_merge_seconds histogram")) << m->body;
  // The page and its script are served.
  auto page = c2.Get("/");
  ASSERT_TRUE(page);
  EXPECT_TRUE(contains(page->body, "<script src=\"/dashboard.js\"")) << page->body.substr(0, 300);
  EXPECT_TRUE(contains(page->get_header_value("Content-Security-Policy"), "default-src 'self'"));
}

TEST_F(BrokerHttpTest, HeadersAreBoundedBeforeTheyAreStored) {
  start(/*private_jobs=*/false);
  const auto url = broker->http_url();
  const int port = std::stoi(url.substr(url.rfind(':') + 1));
  // A million small headers (8 MB), sent as fast as the socket takes them: answered 431 after
  // the first 100, and the master's memory does not grow with them (parsed and kept, they took
  // over 100 MB).
  std::string bomb = "GET /api/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\n";
  bomb.reserve(bomb.size() + 8'000'002);
  for (int i = 0; i < 1'000'000; ++i) bomb += "X-a: b\r\n";
  bomb += "\r\n";
  ASSERT_TRUE(reset_peak());
  const uint64_t before = peak_rss();
  EXPECT_EQ(raw_exchange(port, bomb), "HTTP/1.1 431 Request Header Fields Too Large");
  const uint64_t grown = peak_rss() - before;
  std::printf("peak memory grew by %.1f MB while a million headers were refused\n", grown / 1e6);
  EXPECT_LT(grown, uint64_t{24} << 20);
  bomb.clear();
  bomb.shrink_to_fit();
  // One long header line past 64 KiB, and a head that never ends: the same.
  EXPECT_EQ(raw_exchange(port, "GET / HTTP/1.1\r\nX-a: " + std::string(70 * 1024, 'b') + "\r\n\r\n"),
            "HTTP/1.1 431 Request Header Fields Too Large");
  EXPECT_EQ(raw_exchange(port, "GET / HTTP/1.1\r\n" + std::string(70 * 1024, '\n')),
            "HTTP/1.1 431 Request Header Fields Too Large");
  // Within the bounds, a request with many headers is served, on a connection kept alive for
  // the next one.
  std::string fine = "GET /api/session HTTP/1.1\r\nHost: 127.0.0.1\r\n";
  for (size_t i = 1; i < kMaxHeaderLines; ++i) fine += "X-a: b\r\n";
  EXPECT_EQ(raw_exchange(port, fine + "\r\n"), "HTTP/1.1 200 OK");
  auto h = http();
  for (int i = 0; i < 3; ++i) {
    auto res = h.Get("/api/session");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200);
  }
  auto m = h.Get("/metrics");
  ASSERT_TRUE(m);
  EXPECT_TRUE(contains(m->body, "rayfarm_http_responses_total{code=\"431\"} 3")) << m->body;
}

TEST_F(BrokerHttpTest, TheAuthSchemeIsReadInAnyCaseAndOnlyOnce) {
  start(/*private_jobs=*/false);
  const std::string owner = token("owner"), other = token("other");
  auto h = http();
  for (const char* scheme : {"Bearer ", "bearer ", "BEARER   "}) {
    auto res = h.Get("/api/session", {{"Authorization", scheme + owner}});
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << scheme;
    EXPECT_EQ(json::parse(res->body)["key"], "owner") << scheme;
  }
  for (const char* bad : {"Bearer", "Bearerx", "Basic b3duZXI6", "Bearer "}) {
    auto res = h.Get("/api/session", {{"Authorization", bad}});
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 401) << bad;
  }
  // Two credentials: neither is taken, whichever comes first.
  auto res = h.Get("/api/session",
                   {{"Authorization", "Bearer " + owner}, {"Authorization", "Bearer " + other}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 401);
  EXPECT_TRUE(contains(res->body, "2 Authorization headers")) << res->body;
}

TEST_F(BrokerHttpTest, SlowHttpClientsDelayThePageNotTheFarm) {
  start(/*private_jobs=*/false);
  // As many unfinished requests as the HTTP side has threads (HttpOptions::threads): each holds
  // one until its silence runs out.
  const auto url = broker->http_url();
  const int port = std::stoi(url.substr(url.rfind(':') + 1));
  std::vector<int> idle;
  for (int i = 0; i < HttpOptions{}.threads; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
    const char* partial = "GET /api/jobs HTTP/1.1\r\nHost: x\r\n";  // never finished
    ASSERT_GT(::send(fd, partial, std::strlen(partial), 0), 0);
    idle.push_back(fd);
  }
  // The client socket answers at once meanwhile: the reactor does not wait on the HTTP side.
  auto c = client("owner");
  for (int i = 0; i < 5; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    c->send(protocol::encode(wire::ListJobs{}));
    auto reply = test_peer::next(*c);
    ASSERT_TRUE(reply && reply->as<wire::JobList>());
    EXPECT_LT(std::chrono::steady_clock::now() - t0, milliseconds{1000});
  }
  // The page is served again once the idle connections time out.
  auto h = http();
  h.set_read_timeout(30, 0);
  const auto asked = std::chrono::steady_clock::now();
  auto res = h.Get("/api/session");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  std::printf("the page answered after %.1f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - asked).count());
  for (int fd : idle) ::close(fd);
}

TEST_F(BrokerHttpTest, PrivateJobsAreHiddenFromOtherKeysAndFromNoKey) {
  start(/*private_jobs=*/true);
  const std::string id = submit("owner");
  const std::string owner = token("owner"), other = token("other"), boss = token("boss");
  EXPECT_EQ(get("/api/jobs").second["jobs"].size(), 0u);
  EXPECT_EQ(get("/api/jobs", other).second["jobs"].size(), 0u);
  EXPECT_EQ(get("/api/jobs", owner).second["jobs"].size(), 1u);
  EXPECT_EQ(get("/api/jobs", boss).second["jobs"].size(), 1u);
  EXPECT_EQ(get("/api/jobs/" + id, other).first, 404);
  EXPECT_EQ(get("/api/jobs/" + id + "/image.png", other).first, 404);
  EXPECT_EQ(post("/api/jobs/" + id + "/cancel", other).first, 404);  // not even named
  EXPECT_EQ(get("/api/jobs/" + id, owner).first, 200);
  // A worker's units name their jobs: hidden as the jobs are (none here: no worker).
  EXPECT_EQ(get("/api/workers").first, 200);
}

TEST_F(BrokerHttpTest, AJobsDetailAndAWorkersControlsFollowTheKeysRights) {
  clients.emplace("w1", net::generate_key_pair());  // the client key of the worker key's name
  MasterOptions o = options(/*private_jobs=*/true);
  o.heartbeat.liveness = 100000;  // the test's worker sends no heartbeats
  start(o);
  const std::string id = submit("owner");
  const std::string owner = token("owner"), other = token("other"), boss = token("boss"),
                    w1 = token("w1");
  auto [status, detail] = get("/api/jobs/" + id + "/detail", owner);
  ASSERT_EQ(status, 200) << detail.dump();
  EXPECT_EQ(detail["status"]["job_id"], id);
  EXPECT_NE(detail["status"]["submitted_unix_ms"], "0");
  ASSERT_FALSE(detail["log"].empty());
  EXPECT_EQ(detail["log"][0]["text"].get<std::string>().rfind("accepted", 0), 0u);
  EXPECT_EQ(get("/api/jobs/" + id + "/detail", other).first, 404);
  EXPECT_EQ(get("/api/jobs/" + id + "/detail").first, 404);
  EXPECT_EQ(get("/api/jobs/" + id + "/detail", boss).first, 200);

  net::Dealer worker(
      broker->worker_endpoint(), net::kDefaultMaxMessageBytes,
      net::Curve{worker_keys.public_key, worker_keys.secret_key, master_keys.public_key, ""});
  ASSERT_TRUE(worker.send(protocol::encode(test_peer::hello(wire::ROLE_WORKER))));
  ASSERT_TRUE(test_peer::next(worker));
  ASSERT_TRUE(worker.send(protocol::encode(wire::WorkRequest{})));
  const auto unit = test_peer::next(worker);
  ASSERT_TRUE(unit && unit->as<wire::WorkUnit>());
  // Who may change the worker: its key's namesake and the admin; the page reads it per worker.
  std::string wid;
  for (const auto& [name, may] : std::vector<std::pair<std::string, bool>>{
           {w1, true}, {boss, true}, {other, false}, {"", false}}) {
    json workers;
    for (int i = 0; i < 100; ++i) {  // the snapshot shows the worker within a second
      workers = get("/api/workers", name).second;
      if (!workers["workers"].empty() && !workers["workers"][0]["units"].empty()) break;
      std::this_thread::sleep_for(std::chrono::milliseconds{20});
    }
    ASSERT_EQ(workers["workers"].size(), 1u) << workers.dump();
    EXPECT_EQ(workers["workers"][0]["can_manage"], may) << workers.dump();
    EXPECT_EQ(workers["workers"][0]["control"], "enabled");
    wid = workers["workers"][0]["id"];
  }
  const std::string path = "/api/workers/" + wid;
  EXPECT_EQ(post(path + "/drain", "").first, 401);
  EXPECT_EQ(post(path + "/drain", other).first, 403);
  EXPECT_EQ(post("/api/workers/0123456789/drain", boss).first, 404);
  auto [drained, d] = post(path + "/drain", w1);
  ASSERT_EQ(drained, 200) << d.dump();
  EXPECT_EQ(d["worker"]["control"], "draining");
  auto [disabled, x] = post(path + "/disable", boss);
  ASSERT_EQ(disabled, 200) << x.dump();
  EXPECT_EQ(x["worker"]["control"], "disabled");
  EXPECT_EQ(x["units_requeued"], 1);
  auto [enabled, e] = post(path + "/enable", w1);
  ASSERT_EQ(enabled, 200) << e.dump();
  EXPECT_EQ(e["worker"]["control"], "enabled");
  // The job's log says where its unit went.
  const json log = get("/api/jobs/" + id + "/detail", owner).second["log"];
  EXPECT_NE(log.dump().find("its worker was disabled by key 'boss'"), std::string::npos)
      << log.dump();
}

TEST_F(BrokerHttpTest, BeyondLoopbackReadingNeedsATokenUnlessAllowed) {
  for (bool anonymous : {false, true}) {
    MasterOptions o = options(/*private_jobs=*/false);
    o.http_endpoint = "0.0.0.0:0";
    o.http_anonymous_read = anonymous;
    o.data_dir = dir.path() / ("data" + std::to_string(anonymous));
    start(o);
    auto h = http();
    auto jobs = h.Get("/api/jobs");
    auto metrics_page = h.Get("/metrics");
    auto page = h.Get("/");
    auto signed_in = h.Get("/api/jobs", bearer(token("owner")));
    halt();
    ASSERT_TRUE(jobs && metrics_page && page && signed_in);
    EXPECT_EQ(jobs->status, anonymous ? 200 : 401) << jobs->body;
    EXPECT_EQ(metrics_page->status, 200);  // counts only, for Prometheus
    EXPECT_EQ(page->status, 200);          // the page, which then asks for a token
    EXPECT_EQ(signed_in->status, 200);
  }
}

}  // namespace
}  // namespace rayfarm::master
