// Sharing the farm through the CLI, with real processes on loopback and CURVE keys: a job
// submitted paused waits while another renders, and once resumed renders to the image of a local
// render; priorities are set at submission and changed later; a key that is not an admin may
// neither raise a job above the master's cap nor touch another key's job. Every wait is bounded;
// every process is killed by PID at the end.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "common/net/keys.h"
#include "tests/e2e/farm_fixture.h"

namespace rayfarm::test {
namespace {

class SharingTest : public FarmFixture {
 protected:
  void SetUp() override {
    FarmFixture::SetUp();
    make_keys(keys(), {{"admin", "clients"}, {"bob", "clients"}, {"w1", "workers"}});
    admin_keys_ = net::read_key_pair(keys() / "own" / "admin.key_secret");
    master_public_ = net::read_key_pair(keys() / "master.key_secret").public_key;
  }
  fs::path keys() const { return dir() / "keys"; }
  std::vector<std::string> auth_of(const std::string& name) const {
    return {"--key", (keys() / "own" / (name + ".key_secret")).string(), "--master-key",
            (keys() / "master.key").string()};
  }
  std::vector<std::string> client_auth() const override { return auth_of("admin"); }
  net::Curve client_curve() const override {
    return {admin_keys_.public_key, admin_keys_.secret_key, master_public_, ""};
  }
  RunResult as_bob(std::vector<std::string> args) {
    return cli(std::move(args), true, std::chrono::milliseconds{90000}, auth_of("bob"));
  }

 private:
  net::KeyPair admin_keys_;
  std::string master_public_;
};

TEST_F(SharingTest, PausedJobsWaitPrioritiesChangeAndOnlyAdminsGoAboveTheCap) {
  run_master("master.log", {"--heartbeat-ms", "200", "--liveness", "3", "--key",
                            (keys() / "master.key_secret").string(), "--worker-keys",
                            (keys() / "workers").string(), "--client-keys",
                            (keys() / "clients").string(), "--admin-clients", "admin"});
  const fs::path scene = small_scene("furnace", 16);
  const std::vector<std::string> settings{"--spp", "8", "--seed", "3"};

  // Bob's job at the default priority; above the cap (0 by default) is refused, naming it.
  std::vector<std::string> args{"submit", scene.string(), "--spp", "8", "--seed", "3"};
  const RunResult bobs = as_bob(args);
  ASSERT_EQ(bobs.code, 0) << bobs.err;
  const std::string bob_job = bobs.out.substr(0, bobs.out.find('\n'));
  args.insert(args.end(), {"--priority", "5"});
  const RunResult too_high = as_bob(args);
  EXPECT_EQ(too_high.code, 1);
  EXPECT_NE(too_high.err.find("priority 5 is above what key 'bob' may give a job (at most 0"),
            std::string::npos)
      << too_high.err;

  // The admin's job, paused, at priority 10.
  std::vector<std::string> paused_settings = settings;
  paused_settings.insert(paused_settings.end(), {"--priority", "10", "--paused"});
  const std::string held = submit(scene, paused_settings);
  const auto shown = nlohmann::json::parse(cli({"status", held, "--json"}).out);
  EXPECT_EQ(shown["paused"], true);
  EXPECT_EQ(shown["priority"], 10);
  EXPECT_EQ(shown["state"], "queued");
  EXPECT_TRUE(has_line(cli({"list"}).out, held, "paused"));

  // Bob may not touch the admin's job, nor raise his own past the cap; he may lower his own.
  const RunResult not_his = as_bob({"resume", held});
  EXPECT_EQ(not_his.code, 1);
  EXPECT_NE(not_his.err.find("belongs to key 'admin'"), std::string::npos) << not_his.err;
  const RunResult raise = as_bob({"set-priority", bob_job, "3"});
  EXPECT_EQ(raise.code, 1);
  EXPECT_NE(raise.err.find("at most 0"), std::string::npos) << raise.err;
  const RunResult lower = as_bob({"set-priority", bob_job, "-5"});
  ASSERT_EQ(lower.code, 0) << lower.err;
  EXPECT_EQ(lower.out, "job " + bob_job + " queued, priority -5\n");
  // Out of range is a usage error of the CLI, before anything is sent.
  const RunResult out_of_range = cli({"set-priority", bob_job, "101"});
  EXPECT_EQ(out_of_range.code, 2);
  EXPECT_NE(out_of_range.err.find("101"), std::string::npos) << out_of_range.err;

  // A worker joins: Bob's job renders, the paused one gets nothing.
  run_worker("w1", {"--threads", "1", "--heartbeat-ms", "200", "--liveness", "3", "--key",
                    (keys() / "own" / "w1.key_secret").string(), "--master-key",
                    (keys() / "master.key").string()});
  wait_for_state(bob_job, wire::JOB_DONE);
  const wire::JobStatus waiting = status(held);
  EXPECT_EQ(waiting.state(), wire::JOB_QUEUED);
  EXPECT_TRUE(waiting.paused());
  EXPECT_EQ(waiting.units_done(), 0u);
  EXPECT_EQ(waiting.units_leased(), 0u);

  // Resumed, it renders to the local image, bit for bit.
  const RunResult resumed = cli({"resume", held});
  ASSERT_EQ(resumed.code, 0) << resumed.err;
  EXPECT_EQ(resumed.out, "job " + held + " queued, priority 10\n");
  wait_for_state(held, wire::JOB_DONE);
  EXPECT_FALSE(status(held).paused());
  EXPECT_TRUE(bit_identical(fetch(held), local_render(scene, settings)));
  // A finished job cannot be paused.
  const RunResult late = cli({"pause", held});
  EXPECT_EQ(late.code, 1);
  EXPECT_NE(late.err.find("only a queued or running job"), std::string::npos) << late.err;
}

}  // namespace
}  // namespace rayfarm::test
