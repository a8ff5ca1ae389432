// The worker's agent against a real master socket on loopback whose ZAP handler refuses every key:
// the worker keeps knocking, and the heartbeats it cannot send are logged once, not once each.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <sstream>
#include <thread>

#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/net/zap.h"
#include "tests/support/temp_dir.h"
#include "worker/agent.h"

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

}  // namespace
}  // namespace rayfarm::worker
