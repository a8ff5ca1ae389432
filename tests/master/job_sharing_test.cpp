// Sharing the farm, through the job manager without sockets: priorities decide which job's units
// go out first; a job submitted paused, or paused later, hands out nothing and its clock (its time
// limit) stops until it is resumed; both are checked, kept in the job's record across a master
// restart, and cleared or kept as a finished or retried job needs.
#include <gtest/gtest.h>

#include <chrono>
#include <optional>
#include <thread>

#include "common/limits.h"
#include "master/job_manager.h"
#include "tests/master/job_requests.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {

using test_jobs::furnace_job;
using test_jobs::result_for;
using testing::TempDir;

class JobSharingTest : public ::testing::Test {
 protected:
  TempDir dir;
  JobStore store{dir.path() / "data"};
  JobManager jobs{store};

  std::string submit(int32_t priority, bool paused = false, uint32_t spp = 8) {
    wire::SubmitJob request = furnace_job(spp, 16, 4);  // 4 tiles x spp/4 passes
    request.set_priority(priority);
    request.set_paused(paused);
    return jobs.submit(request);
  }
  /// The job of the next unit a worker gets; "" when none.
  std::string next_job(const std::string& worker) {
    const auto unit = jobs.next_unit(worker);
    return unit ? unit->job_id() : std::string();
  }
};

TEST_F(JobSharingTest, TheHigherPriorityJobsUnitsGoOutFirst) {
  const std::string low = submit(-3, false, 4);
  const std::string high = submit(7, false, 4);
  EXPECT_EQ(jobs.status(high, 0)->priority(), 7);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(next_job("w" + std::to_string(i)), high);
  EXPECT_EQ(next_job("w9"), low) << "high has no unit left";
  // Raised above the other while both wait.
  const std::string other = submit(0, false, 4);
  ASSERT_NE(jobs.change(other, 50, std::nullopt), nullptr);
  EXPECT_EQ(next_job("w10"), other);
  EXPECT_EQ(jobs.status(other, 0)->priority(), 50);
}

TEST_F(JobSharingTest, APausedJobHandsOutNothingUntilResumed) {
  const std::string id = submit(0, /*paused=*/true);
  EXPECT_TRUE(jobs.status(id, 0)->paused());
  EXPECT_EQ(jobs.status(id, 0)->state(), wire::JOB_QUEUED);
  EXPECT_FALSE(jobs.has_pending());
  EXPECT_EQ(next_job("w1"), "");
  const JobRecord* r = jobs.change(id, std::nullopt, false);
  ASSERT_NE(r, nullptr);
  EXPECT_FALSE(r->paused);
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  // Paused with a unit out: that unit's result still counts; no more go out.
  ASSERT_NE(jobs.change(id, std::nullopt, true), nullptr);
  EXPECT_EQ(next_job("w2"), "");
  EXPECT_EQ(jobs.on_result("w1", result_for(*unit)), MergeOutcome::kMerged);
  EXPECT_EQ(jobs.status(id, 0)->units_done(), 1u);
  EXPECT_LT(jobs.status(id, 0)->eta_seconds(), 0.0) << "a paused job has no end to estimate";
  ASSERT_NE(jobs.change(id, std::nullopt, false), nullptr);
  EXPECT_EQ(next_job("w2"), id);
}

TEST_F(JobSharingTest, AChangeIsCheckedAndNamesTheCause) {
  EXPECT_EQ(jobs.change("j4242", 1, std::nullopt), nullptr);
  const std::string id = submit(0, false, 4);
  for (const int32_t bad : {kMaxPriority + 1, kMinPriority - 1}) {
    try {
      jobs.change(id, bad, std::nullopt);
      FAIL() << "accepted priority " << bad;
    } catch (const JobRejected& e) {
      EXPECT_NE(std::string(e.what()).find("priority " + std::to_string(bad)), std::string::npos)
          << e.what();
    }
  }
  EXPECT_EQ(jobs.status(id, 0)->priority(), 0) << "a refused change changes nothing";
  wire::SubmitJob request = furnace_job(4, 16, 4);
  request.set_priority(kMaxPriority + 1);
  EXPECT_THROW(jobs.submit(request), JobRejected);
  // A finished job cannot be paused or given a priority.
  ASSERT_TRUE(jobs.cancel(id));
  try {
    jobs.change(id, std::nullopt, true);
    FAIL() << "paused a cancelled job";
  } catch (const JobRejected& e) {
    EXPECT_NE(std::string(e.what()).find("cancelled"), std::string::npos) << e.what();
  }
}

TEST_F(JobSharingTest, ThePausedTimeDoesNotCountTowardsTheTimeLimit) {
  wire::SubmitJob request = furnace_job(64, 16, 4);
  request.mutable_overrides()->set_time_limit_s(1.0);
  const std::string id = jobs.submit(request);
  ASSERT_TRUE(jobs.next_unit("w1"));  // the clock starts
  ASSERT_NE(jobs.change(id, std::nullopt, true), nullptr);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  jobs.tick();
  auto st = jobs.status(id, 1);
  EXPECT_EQ(st->state(), wire::JOB_RUNNING) << "ended by a limit that counted the pause";
  EXPECT_LT(st->elapsed_seconds(), 1.0);
  const double frozen = st->elapsed_seconds();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(jobs.status(id, 1)->elapsed_seconds(), frozen) << "the clock runs while paused";
  ASSERT_NE(jobs.change(id, std::nullopt, false), nullptr);
  // Resumed where it stopped: the pause is not added back.
  EXPECT_LT(jobs.status(id, 1)->elapsed_seconds(), 1.0);
  jobs.tick();
  EXPECT_EQ(jobs.status(id, 1)->state(), wire::JOB_RUNNING);
  test_jobs::tick_while_running(jobs, id);
  st = jobs.status(id, 1);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->stop_reason(), "time limit");
  EXPECT_GE(st->elapsed_seconds(), 1.0);
}

TEST_F(JobSharingTest, AStartedJobPausedAcrossARestartKeepsItsClockStopped) {
  const std::string id = submit(0, false, 64);
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  ASSERT_EQ(jobs.on_result("w1", result_for(*unit)), MergeOutcome::kMerged);
  ASSERT_NE(jobs.change(id, std::nullopt, true), nullptr);
  const double frozen = jobs.status(id, 1)->elapsed_seconds();
  EXPECT_EQ(jobs.shutdown(), 1u);  // checkpointed
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  JobStore store2(dir.path() / "data");
  JobManager restarted(store2);
  EXPECT_EQ(restarted.recover(), 1u);
  const auto st = restarted.status(id, 1);
  EXPECT_TRUE(st->paused());
  EXPECT_EQ(st->state(), wire::JOB_RUNNING);
  EXPECT_EQ(st->units_done(), 1u);
  EXPECT_NEAR(st->elapsed_seconds(), frozen, 0.05) << "the restart's wait counted as rendering";
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(restarted.status(id, 1)->elapsed_seconds(), st->elapsed_seconds());
  EXPECT_FALSE(restarted.next_unit("w2"));
}

TEST_F(JobSharingTest, PriorityAndPauseSurviveARestartAndARetry) {
  const std::string id = submit(9, /*paused=*/true);
  const std::string other = submit(-2);
  {
    JobStore store2(dir.path() / "data");
    JobManager restarted(store2);
    EXPECT_EQ(restarted.recover(), 2u);
    const auto st = restarted.status(id, 0);
    EXPECT_EQ(st->priority(), 9);
    EXPECT_TRUE(st->paused());
    EXPECT_EQ(restarted.status(other, 0)->priority(), -2);
    const auto unit = restarted.next_unit("w1");
    ASSERT_TRUE(unit);
    EXPECT_EQ(unit->job_id(), other) << "the paused job stays paused";
    ASSERT_NE(restarted.change(id, std::nullopt, false), nullptr);
    EXPECT_EQ(restarted.next_unit("w2")->job_id(), id) << "priority 9 first, once resumed";
    // Cancelled while paused: an ended job is not paused; a retry keeps its priority.
    ASSERT_NE(restarted.change(id, std::nullopt, true), nullptr);
    ASSERT_TRUE(restarted.cancel(id));
    EXPECT_FALSE(restarted.status(id, 0)->paused());
    EXPECT_EQ(restarted.retry(id), wire::JOB_QUEUED);
    EXPECT_EQ(restarted.status(id, 0)->priority(), 9);
    EXPECT_FALSE(restarted.status(id, 0)->paused());
  }
  JobStore store3(dir.path() / "data");
  JobManager again(store3);
  again.recover();
  EXPECT_EQ(again.status(id, 0)->priority(), 9);
  EXPECT_FALSE(again.status(id, 0)->paused());
}

}  // namespace
}  // namespace rayfarm::master
