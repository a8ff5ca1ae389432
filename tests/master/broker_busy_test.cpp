// The broker's count of its busy time: what it spent outside its poll wait, and its polls, read
// from another thread while it serves.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "master/broker.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

TEST(BrokerBusyTest, CountsItsTimeOutsideThePollWaitAndItsPolls) {
  testing::TempDir dir;
  MasterOptions o;
  o.worker_endpoint = "tcp://127.0.0.1:0";
  o.client_endpoint = "tcp://127.0.0.1:0";
  o.data_dir = dir.path() / "data";
  Broker broker(o);
  EXPECT_EQ(broker.busy_seconds(), 0.0);
  EXPECT_EQ(broker.polls(), 0u);

  std::atomic<bool> stop{false};
  const auto start = Clock::now();
  std::thread reactor([&] { broker.run(stop); });
  // Idle, it still polls at least every 100 ms; the counters are read while it runs.
  while (broker.polls() < 3 && Clock::now() - start < std::chrono::seconds{10}) {
    std::this_thread::sleep_for(milliseconds{10});
  }
  const double busy_while_running = broker.busy_seconds();
  stop = true;
  reactor.join();
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();

  EXPECT_GE(broker.polls(), 3u);
  EXPECT_GE(busy_while_running, 0.0);
  EXPECT_LE(busy_while_running, broker.busy_seconds());
  // The waits are not counted: idle, the reactor is busy a small part of the time (polls of up to
  // 100 ms, each followed by a few microseconds of timers).
  EXPECT_LT(broker.busy_seconds(), 0.5 * wall);
}

}  // namespace
}  // namespace rayfarm::master
