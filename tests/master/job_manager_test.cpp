// The master's jobs without sockets: a job is accepted only when its scene loads (the parser's
// message goes back, without the master's scratch paths); units go out, results merge into an
// image written to the data dir; lost workers' units come back; duplicates, cancelled jobs and
// inconsistent results lose nothing already merged; unfinished jobs restart after a restart.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <fstream>
#include <iterator>

#include "common/bundle/bundle.h"
#include "common/image/exr.h"
#include "common/protocol/convert.h"
#include "master/job_manager.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;

using testing::read_file;
using testing::TempDir;

/// A submit request for the bundled furnace (32x32) with these overrides.
wire::SubmitJob furnace_job(uint32_t spp, uint32_t tile, uint32_t pass_spp) {
  const PackedScene packed =
      pack_scene(fs::path(RAYFARM_SOURCE_DIR) / "scenes" / "furnace" / "scene.json");
  wire::SubmitJob request;
  protocol::bundle_to_wire(packed.bundle, request.mutable_bundle());
  request.set_scene_path(packed.scene_path);
  request.set_name("furnace");
  request.mutable_overrides()->set_spp(spp);
  request.mutable_overrides()->set_tile_size(tile);
  request.mutable_overrides()->set_pass_spp(pass_spp);
  return request;
}

wire::SubmitJob job_with_scene_text(const std::string& text) {
  wire::SubmitJob request;
  protocol::bundle_to_wire(make_bundle({{"scene.json", text}}), request.mutable_bundle());
  request.set_scene_path("scene.json");
  return request;
}

/// A result of the right shape for `unit`, every sample worth `value`.
wire::UnitResult result_for(const wire::WorkUnit& unit, double value = 0.5) {
  const TileRect rect = protocol::rect_from_wire(unit.tile());
  TileResult r(rect, {unit.sample_begin(), unit.sample_end()});
  for (auto& s : r.sum) s = to_fixed(value * (unit.sample_end() - unit.sample_begin()));
  return protocol::result_to_wire(unit.job_id(), unit.unit_id(), r, 0.01);
}

class JobManagerTest : public ::testing::Test {
 protected:
  TempDir dir;
  JobStore store{dir.path() / "data"};
  JobManager jobs{store};
};

TEST_F(JobManagerTest, ABadSceneIsRejectedWithTheParsersMessage) {
  try {
    jobs.submit(job_with_scene_text("{ \"camera\": [1, 2"));
    FAIL() << "accepted a broken scene";
  } catch (const JobRejected& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("scene.json"), std::string::npos) << what;
    EXPECT_EQ(what.find("/tmp/"), std::string::npos) << "leaks the master's scratch path: " << what;
  }
  EXPECT_TRUE(jobs.list(0).empty());
  EXPECT_TRUE(fs::is_empty(dir.path() / "data" / "tmp"));
}

TEST_F(JobManagerTest, TheScenePathMustBeInTheBundle) {
  wire::SubmitJob request = furnace_job(4, 16, 4);
  request.set_scene_path("other.json");
  EXPECT_THROW(jobs.submit(request), JobRejected);
  request.set_scene_path("../scene.json");
  EXPECT_THROW(jobs.submit(request), JobRejected);
}

TEST_F(JobManagerTest, ABadBundleOrBadOverridesAreRejected) {
  wire::SubmitJob request = furnace_job(4, 16, 4);
  request.mutable_bundle()->mutable_files(0)->set_path("/abs.json");
  EXPECT_THROW(jobs.submit(request), JobRejected);
  request = furnace_job(4, 16, 4);
  request.mutable_overrides()->set_integrator(static_cast<wire::Integrator>(42));
  EXPECT_THROW(jobs.submit(request), JobRejected);
  request = furnace_job(4, 5000, 4);
  EXPECT_THROW(jobs.submit(request), JobRejected);
}

TEST_F(JobManagerTest, AJobRunsToCompletionAndWritesItsImage) {
  const std::string id = jobs.submit(furnace_job(8, 16, 4));  // 4 tiles x 2 passes
  EXPECT_EQ(id, "j0001");
  auto st = jobs.status(id, 1);
  ASSERT_TRUE(st);
  EXPECT_EQ(st->state(), wire::JOB_QUEUED);
  EXPECT_EQ(st->units_total(), 8u);
  EXPECT_EQ(st->width(), 32u);
  EXPECT_EQ(st->settings().spp(), 8u);
  EXPECT_THROW(jobs.image(id), JobRejected);  // nothing merged yet

  std::vector<wire::WorkUnit> units;
  while (auto unit = jobs.next_unit("w1")) units.push_back(*unit);
  ASSERT_EQ(units.size(), 8u);
  for (uint32_t i = 0; i < 8; ++i) EXPECT_EQ(units[i].pass(), i / 4);
  EXPECT_EQ(jobs.status(id, 1)->state(), wire::JOB_RUNNING);

  for (const auto& unit : units)
    EXPECT_EQ(jobs.on_result("w1", result_for(unit)), MergeOutcome::kMerged);
  st = jobs.status(id, 1);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->units_done(), 8u);
  EXPECT_EQ(st->spp_done(), 8u);
  EXPECT_EQ(st->passes_done(), 2u);

  const Image image = read_exr(dir.path() / "data" / "jobs" / id / "image.exr");
  EXPECT_EQ(image.width, 32u);
  EXPECT_EQ(image.attributes.at("rayfarm:spp"), "8");
  EXPECT_EQ(image.attributes.at("rayfarm:job"), id);
  EXPECT_EQ(image.rgb[0], 0.5f);
  EXPECT_TRUE(fs::exists(dir.path() / "data" / "jobs" / id / "image.png"));
  const wire::ImageData data = jobs.image(id);
  EXPECT_EQ(data.exr(), read_file(dir.path() / "data" / "jobs" / id / "image.exr"));
  EXPECT_FALSE(data.png().empty());

  // A late duplicate changes nothing.
  EXPECT_EQ(jobs.on_result("w2", result_for(units[3], 9.0)), MergeOutcome::kDuplicate);
  EXPECT_EQ(read_exr(dir.path() / "data" / "jobs" / id / "image.exr").rgb, image.rgb);
}

TEST_F(JobManagerTest, DuplicatesWhileRunningAreDroppedAndLostWorkersUnitsComeBack) {
  const std::string id = jobs.submit(furnace_job(4, 16, 4));  // 4 units
  const auto a = jobs.next_unit("w1");
  const auto b = jobs.next_unit("w1");
  ASSERT_TRUE(a && b);
  EXPECT_EQ(jobs.on_result("w1", result_for(*a)), MergeOutcome::kMerged);
  EXPECT_EQ(jobs.on_result("w1", result_for(*a, 3.0)), MergeOutcome::kDuplicate);
  EXPECT_EQ(jobs.release_worker("w1"), 1u);  // b goes back
  const auto again = jobs.next_unit("w2");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->unit_id(), b->unit_id());
  // The lost worker's late result still counts; w2's copy is then a duplicate.
  EXPECT_EQ(jobs.on_result("w1", result_for(*b)), MergeOutcome::kMerged);
  EXPECT_EQ(jobs.on_result("w2", result_for(*again)), MergeOutcome::kDuplicate);
  EXPECT_EQ(jobs.status(id, 0)->units_done(), 2u);
}

TEST_F(JobManagerTest, InconsistentResultsAreRejectedAndTheUnitRequeued) {
  jobs.submit(furnace_job(4, 16, 4));
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  wire::UnitResult bad = result_for(*unit);
  bad.mutable_sum()->resize(bad.sum().size() - 16);
  EXPECT_EQ(jobs.on_result("w1", bad), MergeOutcome::kRejected);
  bad = result_for(*unit);
  bad.set_sample_end(bad.sample_end() + 1);
  EXPECT_EQ(jobs.on_result("w1", bad), MergeOutcome::kRejected);
  const auto again = jobs.next_unit("w2");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->unit_id(), unit->unit_id());
  wire::UnitResult unknown = result_for(*unit);
  unknown.set_job_id("j9999");
  EXPECT_EQ(jobs.on_result("w1", unknown), MergeOutcome::kRejected);
}

TEST_F(JobManagerTest, RepeatedUnitFailuresFailTheJob) {
  const std::string id = jobs.submit(furnace_job(4, 16, 4));
  for (int attempt = 0; attempt < 3; ++attempt) {
    const auto unit = jobs.next_unit("w1");
    ASSERT_TRUE(unit);
    EXPECT_EQ(unit->unit_id(), 0u);
    wire::UnitFailed failed;
    failed.set_job_id(id);
    failed.set_unit_id(0);
    failed.set_reason("out of memory");
    jobs.on_unit_failed("w1", failed);
  }
  const auto st = jobs.status(id, 0);
  EXPECT_EQ(st->state(), wire::JOB_FAILED);
  EXPECT_NE(st->error().find("out of memory"), std::string::npos);
  EXPECT_FALSE(jobs.next_unit("w1"));
}

TEST_F(JobManagerTest, CancelStopsHandingOutUnitsAndKeepsTheImage) {
  const std::string id = jobs.submit(furnace_job(8, 16, 4));
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  jobs.on_result("w1", result_for(*unit));
  EXPECT_EQ(jobs.cancel(id), std::optional<wire::JobState>(wire::JOB_CANCELLED));
  EXPECT_FALSE(jobs.next_unit("w1"));
  EXPECT_EQ(jobs.on_result("w1", result_for(*unit)), MergeOutcome::kRejected);
  EXPECT_NO_THROW(jobs.image(id));
  EXPECT_FALSE(jobs.cancel("j4242"));
  EXPECT_FALSE(jobs.status("j4242", 0));
}

TEST_F(JobManagerTest, UnfinishedJobsRestartAfterAMasterRestart) {
  const std::string done_id = jobs.submit(furnace_job(4, 32, 4));  // 1 unit
  const auto unit = jobs.next_unit("w1");
  jobs.on_result("w1", result_for(*unit));
  const std::string running_id = jobs.submit(furnace_job(8, 16, 4));
  ASSERT_TRUE(jobs.next_unit("w1"));

  JobStore store2(dir.path() / "data");
  JobManager restarted(store2);
  EXPECT_EQ(restarted.recover(), 1u);
  EXPECT_EQ(restarted.status(done_id, 0)->state(), wire::JOB_DONE);
  EXPECT_EQ(restarted.status(running_id, 0)->state(), wire::JOB_QUEUED);
  const auto first = restarted.next_unit("w2");
  ASSERT_TRUE(first);
  EXPECT_EQ(first->job_id(), running_id);
  EXPECT_EQ(first->unit_id(), 0u);
  // The bundle is served from the data dir, and new ids do not collide.
  EXPECT_TRUE(restarted.bundle(first->bundle_hash()));
  EXPECT_EQ(restarted.submit(furnace_job(4, 32, 4)), "j0003");
}

}  // namespace
}  // namespace rayfarm::master
