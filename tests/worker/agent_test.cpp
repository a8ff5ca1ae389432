// The worker's agent against a real master socket on loopback: one whose ZAP handler refuses every
// key (the worker keeps knocking, and the heartbeats it cannot send are logged once, not once
// each), and one played by the test, whose errors the worker acts on by their code, not their text.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <optional>
#include <sstream>
#include <thread>

#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/net/zap.h"
#include "common/protocol/codec.h"
#include "tests/support/temp_dir.h"
#include "worker/agent.h"
#include "worker/connection.h"

namespace rayfarm::worker {
namespace {

using std::chrono::milliseconds;
using testing::TempDir;

size_t lines_with(const std::string& text, const std::string& part) {
  std::istringstream in(text);
  size_t n = 0;
  for (std::string line; std::getline(in, line);) n += line.find(part) != std::string::npos;
  return n;
}

TEST(AgentTest, ARefusedWorkerLogsItsDroppedMessagesOnceNotOncePerMessage) {
  TempDir dir;
  const net::KeyPair master = net::generate_key_pair(), worker = net::generate_key_pair();
  net::ZapHandler zap([](const net::ZapRequest&) { return net::ZapVerdict{}; });  // refuses all
  net::Router router("tcp://127.0.0.1:0", net::kDefaultMaxMessageBytes,
                     {master.public_key, master.secret_key, "", "workers"});
  AgentOptions options;
  options.master = router.endpoint();
  options.threads = 1;
  options.cache_dir = dir.path() / "cache";
  options.name = "refused";
  options.heartbeat.interval = milliseconds{10};  // a heartbeat to drop every 10 ms
  options.heartbeat.liveness = 1000;              // on one connection, not reconnecting for 10 s
  options.curve = {worker.public_key, worker.secret_key, master.public_key, ""};
  Agent agent(options);

  constexpr uint64_t kDrops = 20;
  std::atomic<bool> stop{false};
  ::testing::internal::CaptureStderr();
  std::thread runner([&] { agent.run(stop); });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds{30};
  while (agent.messages_dropped() < kDrops && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(milliseconds{10});
  }
  stop.store(true);
  runner.join();
  const std::string log = ::testing::internal::GetCapturedStderr();

  ASSERT_GE(agent.messages_dropped(), kDrops) << log;
  EXPECT_GE(zap.refusals(), 1u);
  EXPECT_EQ(lines_with(log, "message dropped"), 1u) << log;
  EXPECT_EQ(lines_with(log, "no connection to the master takes messages (it has not let this "
                            "worker in); message dropped, logged at most every 60 s"),
            1u)
      << log;
  EXPECT_EQ(lines_with(log, "did not let this worker in: authentication refused"), 1u) << log;
}

/// The master's worker socket, played by the test on loopback without keys.
class FakeMaster {
 public:
  FakeMaster() : router_("tcp://127.0.0.1:0") {}
  std::string endpoint() const { return router_.endpoint(); }

  /// The worker's next message other than a Heartbeat; fails the test after 10 s without one.
  protocol::Decoded next() {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds{10};
    while (std::chrono::steady_clock::now() < deadline) {
      auto delivery = router_.receive(milliseconds{50});
      if (!delivery) continue;
      peer_ = delivery->peer;
      protocol::Decoded msg = protocol::decode(delivery->frames);
      if (!msg.as<wire::Heartbeat>()) return msg;
    }
    ADD_FAILURE() << "the worker sent nothing for 10 s";
    return {};
  }

  /// The worker's next message of type T, counting the Hellos it said before it.
  template <class T>
  size_t hellos_before() {
    size_t hellos = 0;
    for (int i = 0; i < 100; ++i) {
      const protocol::Decoded msg = next();
      if (msg.type.empty() || msg.as<T>()) return hellos;
      hellos += msg.as<wire::Hello>() != nullptr;
    }
    ADD_FAILURE() << "no " << T::descriptor()->full_name() << " in 100 messages";
    return hellos;
  }

  void send(const net::Frames& frames) { ASSERT_TRUE(peer_ && router_.send(*peer_, frames)); }

  /// Takes the worker's Hello, welcomes it, and waits for it to ask for work.
  void welcome() {
    ASSERT_NE(next().as<wire::Hello>(), nullptr);
    send(protocol::encode(wire::Welcome{}));
    EXPECT_EQ(hellos_before<wire::WorkRequest>(), 0u);
  }

  /// Sends an Error, then a unit the worker fails at once (its bundle hash is not one): the
  /// worker's UnitFailed comes after whatever the Error made it send.
  void send_error_then_probe(wire::Error::Code code, const std::string& message) {
    wire::Error error;
    error.set_code(code);
    error.set_message(message);
    send(protocol::encode(std::move(error)));
    wire::WorkUnit probe;
    probe.set_job_id("probe");
    probe.set_bundle_hash("not a hash");
    send(protocol::encode(std::move(probe)));
  }

 private:
  net::Router router_;
  std::optional<net::PeerId> peer_;
};

/// A worker of one thread serving `master`, stopped and joined when it goes out of scope.
class RunningAgent {
 public:
  RunningAgent(const FakeMaster& master, const TempDir& dir) : agent_(options(master, dir)) {
    runner_ = std::thread([this] { code_ = agent_.run(stop_); });
  }
  ~RunningAgent() { stop(); }
  int stop() {
    stop_.store(true);
    if (runner_.joinable()) runner_.join();
    return code_;
  }

 private:
  static AgentOptions options(const FakeMaster& master, const TempDir& dir) {
    AgentOptions o;
    o.master = master.endpoint();
    o.threads = 1;
    o.cache_dir = dir.path() / "cache";
    o.name = "agent-test";
    o.heartbeat.interval = milliseconds{50};
    o.heartbeat.liveness = 1000;  // the test's master never heartbeats: no reconnection
    return o;
  }

  Agent agent_;
  std::atomic<bool> stop_{false};
  int code_ = -1;
  std::thread runner_;
};

TEST(AgentTest, AnUnknownWorkerCodeMakesTheWorkerSayHelloAgainWhateverTheText) {
  TempDir dir;
  FakeMaster master;
  RunningAgent agent(master, dir);
  master.welcome();
  master.send_error_then_probe(wire::Error::UNKNOWN_WORKER, "who are you? (words no worker knows)");
  EXPECT_EQ(master.hellos_before<wire::UnitFailed>(), 1u);
  EXPECT_EQ(agent.stop(), 0);
}

TEST(AgentTest, TheWordsUnknownWorkerUnderAnotherCodeLeaveTheWorkerWelcomed) {
  TempDir dir;
  FakeMaster master;
  RunningAgent agent(master, dir);
  master.welcome();
  master.send_error_then_probe(wire::Error::BAD_REQUEST, "unknown worker: send Hello first");
  EXPECT_EQ(master.hellos_before<wire::UnitFailed>(), 0u);
  // Still welcomed: it asks for work again, and says goodbye when it stops.
  EXPECT_EQ(master.hellos_before<wire::WorkRequest>(), 0u);
  EXPECT_EQ(agent.stop(), 0);
  EXPECT_EQ(master.hellos_before<wire::Goodbye>(), 0u);
}

TEST(ConnectionTest, MovesOnlyAlongItsDiagramAndHoldsResultsUntilWelcomed) {
  using State = Connection::State;
  FakeMaster master;
  wire::Hello hello;
  hello.set_name("connection-test");
  Connection c(master.endpoint(), {}, {}, hello);
  EXPECT_EQ(c.state(), State::kClosed);
  EXPECT_THROW(c.welcome(), std::logic_error);
  EXPECT_THROW(c.greet_again(), std::logic_error);
  EXPECT_THROW(c.refuse(), std::logic_error);

  c.open();
  EXPECT_EQ(c.state(), State::kGreeting);
  EXPECT_EQ(master.next().as<wire::Hello>()->name(), "connection-test");
  EXPECT_THROW(c.open(), std::logic_error);
  EXPECT_THROW(c.greet_again(), std::logic_error);
  wire::UnitFailed held;
  held.set_job_id("held");
  c.send_when_welcomed(protocol::encode(held));  // not yet: the master does not know it

  c.welcome();
  EXPECT_TRUE(c.welcomed());
  const protocol::Decoded sent = master.next();
  ASSERT_NE(sent.as<wire::UnitFailed>(), nullptr) << sent.type;
  EXPECT_EQ(sent.as<wire::UnitFailed>()->job_id(), "held");
  c.welcome();  // a repeated Welcome changes nothing
  EXPECT_TRUE(c.welcomed());

  c.greet_again();
  EXPECT_EQ(c.state(), State::kGreeting);
  EXPECT_NE(master.next().as<wire::Hello>(), nullptr);
  c.refuse();
  EXPECT_TRUE(c.refused());
  EXPECT_THROW(c.welcome(), std::logic_error);
  EXPECT_THROW(c.open(), std::logic_error);
  c.close();  // final: a refused connection stays refused
  EXPECT_TRUE(c.refused());
}

}  // namespace
}  // namespace rayfarm::worker
