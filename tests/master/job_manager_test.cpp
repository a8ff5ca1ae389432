// The master's jobs without sockets: a job is accepted only when its scene loads (the parser's
// message goes back, without the master's scratch paths); units go out, results merge into an
// image written to the data dir; lost workers' units come back; duplicates, cancelled jobs and
// inconsistent results lose nothing already merged; unfinished jobs restart after a restart.
#include <gtest/gtest.h>

#include <functional>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iterator>
#include <thread>

#include "common/bundle/bundle.h"
#include "common/image/exr.h"
#include "common/protocol/convert.h"
#include "master/job_manager.h"
#include "tests/master/job_requests.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;

using test_jobs::furnace_job;
using test_jobs::result_for;
using testing::read_file;
using testing::TempDir;

wire::SubmitJob job_with_scene_text(const std::string& text) {
  wire::SubmitJob request;
  protocol::bundle_to_wire(make_bundle({{"scene.json", text}}), request.mutable_bundle());
  request.set_scene_path("scene.json");
  return request;
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

// A client's shutter overrides are checked as the scene's are, each refusal naming the cause.
TEST_F(JobManagerTest, BadShutterOverridesAreRejectedNamingTheCause) {
  const auto refused = [&](const std::function<void(wire::JobOverrides&)>& set,
                           const std::string& words) {
    wire::SubmitJob request = furnace_job(4, 16, 4);
    set(*request.mutable_overrides());
    try {
      (void)jobs.submit(request);
      ADD_FAILURE() << words << ": accepted";
    } catch (const JobRejected& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  refused([](wire::JobOverrides& o) { o.set_shutter_open(0.f); }, "needs both ends");
  refused([](wire::JobOverrides& o) { o.set_shutter_close(1.f); }, "needs both ends");
  refused(
      [](wire::JobOverrides& o) {
        o.set_shutter_open(1.f);
        o.set_shutter_close(0.f);
      },
      "closes (0) before it opens (1)");
  refused(
      [](wire::JobOverrides& o) {
        o.set_shutter_open(0.f);
        o.set_shutter_close(std::nanf(""));
      },
      "beyond +-100 frames");
  refused([](wire::JobOverrides& o) { o.set_motion_steps(65); }, "65 motion steps");
  wire::SubmitJob good = furnace_job(4, 16, 4);
  good.mutable_overrides()->set_shutter_open(-0.25f);
  good.mutable_overrides()->set_shutter_close(0.25f);
  good.mutable_overrides()->set_motion_steps(3);
  const auto st = jobs.status(jobs.submit(good), 1);
  ASSERT_TRUE(st);
  EXPECT_EQ(st->settings().shutter_open(), -0.25f);
  EXPECT_EQ(st->settings().shutter_close(), 0.25f);
  EXPECT_EQ(st->settings().motion_steps(), 3u);
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
  // A huge tile claimed with a few bytes of sums (a value may pack into one byte) is refused
  // before its sums are decoded: the master allocates nothing for it.
  bad = result_for(*unit);
  bad.mutable_tile()->set_x1(65536);
  bad.mutable_tile()->set_y1(65536);
  bad.set_sum(std::string(size_t{1} << 20, '\0'));
  EXPECT_EQ(jobs.on_result("w1", bad), MergeOutcome::kRejected);
  const auto again = jobs.next_unit("w2");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->unit_id(), unit->unit_id());
  wire::UnitResult unknown = result_for(*unit);
  unknown.set_job_id("j9999");
  EXPECT_EQ(jobs.on_result("w1", unknown), MergeOutcome::kUnleased);
}

TEST_F(JobManagerTest, AUnitThatFailsOnThreeWorkersFailsTheJobWithTheirMessages) {
  const std::string id = jobs.submit(furnace_job(4, 16, 4));
  for (const std::string w : {"w1", "w2", "w3"}) {
    const auto unit = jobs.next_unit(w);
    ASSERT_TRUE(unit);
    EXPECT_EQ(unit->unit_id(), 0u);
    wire::UnitFailed failed;
    failed.set_job_id(id);
    failed.set_unit_id(0);
    failed.set_reason("out of memory on " + w);
    jobs.on_unit_failed(w, failed);
  }
  const auto st = jobs.status(id, 0);
  EXPECT_EQ(st->state(), wire::JOB_FAILED);
  EXPECT_NE(st->error().find("unit 0 failed on 3 different workers"), std::string::npos)
      << st->error();
  for (const char* w : {"w1", "w2", "w3"})
    EXPECT_NE(st->error().find(std::string("out of memory on ") + w), std::string::npos);
  EXPECT_FALSE(jobs.next_unit("w1"));
}

TEST_F(JobManagerTest, AWorkerThatKeepsFailingIsBlockedFromTheJobOnly) {
  const std::string id = jobs.submit(furnace_job(4, 16, 4));  // 4 units
  // The same unit fails three times on one worker: the job goes on, the worker is blocked.
  for (int attempt = 0; attempt < 3; ++attempt) {
    const auto unit = jobs.next_unit("bad");
    ASSERT_TRUE(unit);
    wire::UnitFailed failed;
    failed.set_job_id(id);
    failed.set_unit_id(unit->unit_id());
    failed.set_reason("GPU fell off the bus");
    jobs.on_unit_failed("bad", failed);
  }
  EXPECT_EQ(jobs.status(id, 0)->state(), wire::JOB_RUNNING);
  EXPECT_FALSE(jobs.next_unit("bad")) << "blocked from the only job";
  // Another job's units still go to it; malformed results count like failures.
  const std::string other = jobs.submit(furnace_job(4, 16, 4));
  for (int attempt = 0; attempt < 3; ++attempt) {
    const auto unit = jobs.next_unit("bad");
    ASSERT_TRUE(unit);
    EXPECT_EQ(unit->job_id(), other);
    wire::UnitResult bad = result_for(*unit);
    bad.mutable_sum()->resize(8);
    EXPECT_EQ(jobs.on_result("bad", bad), MergeOutcome::kRejected);
  }
  EXPECT_FALSE(jobs.next_unit("bad"));
  // Good workers finish both jobs.
  while (auto unit = jobs.next_unit("good")) jobs.on_result("good", result_for(*unit));
  EXPECT_EQ(jobs.status(id, 0)->state(), wire::JOB_DONE);
  EXPECT_EQ(jobs.status(other, 0)->state(), wire::JOB_DONE);
}

TEST_F(JobManagerTest, CancelStopsHandingOutUnitsAndKeepsTheImage) {
  const std::string id = jobs.submit(furnace_job(8, 16, 4));
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  jobs.on_result("w1", result_for(*unit));
  EXPECT_EQ(jobs.cancel(id), std::optional<wire::JobState>(wire::JOB_CANCELLED));
  EXPECT_FALSE(jobs.next_unit("w1"));
  // A late result of a cancelled job is routine: discarded, not counted as a wrong result.
  EXPECT_EQ(jobs.on_result("w1", result_for(*unit)), MergeOutcome::kDiscarded);
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

// ---------------------------------------------------------------------------------------------
// Stopping rules: target error, time limit, reference image

/// A 2x2 EXR of constant `value`, as bytes.
std::string constant_exr(const TempDir& dir, uint32_t width, uint32_t height, float value) {
  Image image;
  image.width = width;
  image.height = height;
  image.rgb.assign(size_t{width} * height * 3, value);
  const fs::path path = dir.path() / "reference.exr";
  write_exr(path, image);
  return read_file(path);
}

TEST_F(JobManagerTest, ATargetErrorStopsConvergedTilesAndSaysWhy) {
  wire::SubmitJob request = furnace_job(64, 16, 4);  // 4 tiles x 16 passes
  request.mutable_overrides()->set_target_error(1e-3);
  request.mutable_overrides()->set_min_passes(2);
  const std::string id = jobs.submit(request);
  EXPECT_EQ(jobs.status(id, 1)->units_total(), 64u);

  // Only the first two passes are out; nothing more until they are merged.
  std::vector<wire::WorkUnit> units;
  while (auto unit = jobs.next_unit("w1")) units.push_back(*unit);
  ASSERT_EQ(units.size(), 8u);
  EXPECT_EQ(units.back().pass(), 1u);

  // A result for a unit the rules never released (so never leased) is dropped, and changes
  // nothing.
  wire::WorkUnit never = units.back();
  never.set_unit_id(12);  // pass 3
  never.set_sample_begin(12);
  never.set_sample_end(16);
  EXPECT_EQ(jobs.on_result("w1", result_for(never)), MergeOutcome::kUnleased);

  // Constant samples have no variance: every tile meets the target after its minimum.
  for (const auto& unit : units)
    EXPECT_EQ(jobs.on_result("w1", result_for(unit)), MergeOutcome::kMerged);
  const auto st = jobs.status(id, 1);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->stop_reason(), "target error");
  EXPECT_EQ(st->units_done(), 8u);
  EXPECT_EQ(st->spp_done(), 8u);
  EXPECT_DOUBLE_EQ(st->spp_mean(), 8.0);
  EXPECT_EQ(st->tiles_converged(), 4u);
  EXPECT_EQ(st->tiles_total(), 4u);
  EXPECT_EQ(st->est_rel_mse(), 0.0);
  EXPECT_LT(st->ref_rel_mse(), 0.0) << "no reference, no measured error";

  // The error record is on disk and served with the image.
  const wire::ImageData data = jobs.image(id);
  EXPECT_NE(data.error_csv().find("time_s"), std::string::npos);
  EXPECT_FALSE(data.error_png().empty());
  const Image image = read_exr(dir.path() / "data" / "jobs" / id / "image.exr");
  ASSERT_TRUE(image.extra.count("variance.R"));
  ASSERT_TRUE(image.extra.count("spp.Y"));
  EXPECT_EQ(image.extra.at("spp.Y")[0], 8.0f);
  EXPECT_EQ(image.extra.at("variance.G")[0], 0.0f);

  // The figures survive a master restart.
  JobStore store2(dir.path() / "data");
  JobManager restarted(store2);
  restarted.recover();
  EXPECT_EQ(restarted.status(id, 0)->stop_reason(), "target error");
  EXPECT_DOUBLE_EQ(restarted.status(id, 0)->spp_mean(), 8.0);
}

TEST_F(JobManagerTest, PassesDoneCountsThePassesEveryPixelHasWhileRunningAndWhenDone) {
  // Tile 0 (constant samples) meets the target after its minimum of 2 passes; the other three
  // (noisy samples) never do and run all 16. "pass N/M" must count the passes every pixel has
  // (spp_done / pass_spp) while the job runs, as its finished record does, not the rounds that
  // the open tiles have reached.
  wire::SubmitJob request = furnace_job(64, 16, 4);  // 4 tiles x 16 passes of 4 spp
  request.mutable_overrides()->set_target_error(1e-3);
  request.mutable_overrides()->set_min_passes(2);
  const std::string id = jobs.submit(request);
  const auto result = [](const wire::WorkUnit& unit) {
    const TileRect rect = protocol::rect_from_wire(unit.tile());
    TileResult r(rect, {unit.sample_begin(), unit.sample_end()});
    const double n = unit.sample_end() - unit.sample_begin();
    // Samples of mean 0.5: all 0.5 in tile 0; 0.5 +- 0.87 elsewhere (relMSE ~3 per sample).
    const double mean_square = unit.unit_id() % 4 == 0 ? 0.25 : 1.0;
    for (auto& s : r.sum) s = to_fixed(0.5 * n);
    for (auto& s : r.sum_sq) s = to_fixed(mean_square * n);
    return protocol::result_to_wire(unit.job_id(), unit.unit_id(), r, 0.01);
  };
  uint32_t checked = 0;
  for (int round = 0; round < 32; ++round) {
    std::vector<wire::WorkUnit> units;
    while (auto unit = jobs.next_unit("w1")) units.push_back(*unit);
    if (units.empty()) break;
    for (const auto& unit : units)
      ASSERT_EQ(jobs.on_result("w1", result(unit)), MergeOutcome::kMerged);
    const auto st = jobs.status(id, 1);
    if (st->state() != wire::JOB_RUNNING) break;
    EXPECT_EQ(st->passes_done(), st->spp_done() / 4) << "round " << round;
    EXPECT_LE(st->passes_done(), 2u) << "tile 0 stopped after 2 passes; round " << round;
    ++checked;
  }
  EXPECT_GT(checked, 4u) << "the open tiles went on past tile 0 while running";
  const auto st = jobs.status(id, 1);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->tiles_converged(), 1u);
  EXPECT_EQ(st->spp_done(), 8u);
  EXPECT_EQ(st->passes_done(), 2u);
  EXPECT_EQ(st->passes_total(), 16u);
  EXPECT_DOUBLE_EQ(st->spp_mean(), (8.0 + 3 * 64.0) / 4);
}

/// A JobManager whose leases cover runs of passes: every run as long as allowed once measured.
JobManagerOptions long_runs(uint32_t max_units) {
  JobManagerOptions options;
  options.runs = RunPolicy{std::chrono::hours(1), max_units};
  return options;
}

TEST_F(JobManagerTest, ARunOfPassesIsLeasedAndMergedAsItsUnits) {
  JobManager runs(store, long_runs(8));
  const std::string id = runs.submit(furnace_job(16, 16, 4));  // 4 tiles x 4 passes of 4 spp
  // Unmeasured: one unit. Then tile 1's four passes (units 1, 5, 9, 13) in one lease.
  const auto first = runs.next_unit("w1");
  ASSERT_TRUE(first);
  EXPECT_EQ(first->sample_end(), 4u);
  EXPECT_EQ(runs.on_result("w1", result_for(*first)), MergeOutcome::kMerged);
  const auto run = runs.next_unit("w1");
  ASSERT_TRUE(run);
  EXPECT_EQ(run->unit_id(), 1u);
  EXPECT_EQ(run->pass(), 0u);
  EXPECT_EQ(run->sample_begin(), 0u);
  EXPECT_EQ(run->sample_end(), 16u);
  EXPECT_EQ(runs.on_result("w1", result_for(*run)), MergeOutcome::kMerged);
  EXPECT_EQ(runs.status(id, 1)->units_done(), 5u);

  // A result answering only the first two passes of its lease merges them; the other two go back
  // to the queue at once.
  const auto tile2 = runs.next_unit("w1");
  ASSERT_TRUE(tile2);
  EXPECT_EQ(tile2->sample_end(), 16u);
  wire::WorkUnit half = *tile2;
  half.set_sample_end(8);
  EXPECT_EQ(runs.on_result("w1", result_for(half)), MergeOutcome::kMerged);
  EXPECT_EQ(runs.status(id, 1)->units_done(), 7u);
  const auto back = runs.next_unit("w2");  // unmeasured: one unit, the lowest requeued
  ASSERT_TRUE(back);
  EXPECT_EQ(back->unit_id(), 10u);
  EXPECT_EQ(back->sample_begin(), 8u);
  // w2 holds unit 10 only: a result claiming the run of 10 and 14 was not leased to it as such.
  wire::WorkUnit claimed = *back;
  claimed.set_sample_end(16);
  EXPECT_EQ(runs.on_result("w2", result_for(claimed)), MergeOutcome::kUnleased);
  EXPECT_EQ(runs.on_result("w2", result_for(*back)), MergeOutcome::kMerged);

  // Tile 3's passes go to w1 as a run; w1 is lost and unit 3 merges from w3. The late run
  // overlaps it: the sums cannot be split, so it is a duplicate and adds nothing, and its other
  // units are leased again.
  const auto tile3 = runs.next_unit("w1");  // unit 14 (requeued) first
  ASSERT_TRUE(tile3);
  EXPECT_EQ(tile3->unit_id(), 14u);
  EXPECT_EQ(runs.on_result("w1", result_for(*tile3)), MergeOutcome::kMerged);
  const auto late = runs.next_unit("w1");
  ASSERT_TRUE(late);
  EXPECT_EQ(late->unit_id(), 3u);
  EXPECT_EQ(late->sample_end(), 16u);
  EXPECT_EQ(runs.release_worker("w1"), 4u);
  const auto three = runs.next_unit("w3");
  ASSERT_TRUE(three);
  EXPECT_EQ(three->unit_id(), 3u);
  EXPECT_EQ(three->sample_end(), 4u);
  EXPECT_EQ(runs.on_result("w3", result_for(*three)), MergeOutcome::kMerged);
  EXPECT_EQ(runs.on_result("w1", result_for(*late, 9.0)), MergeOutcome::kDuplicate);
  const auto rest = runs.next_unit("w3");
  ASSERT_TRUE(rest);
  EXPECT_EQ(rest->unit_id(), 7u);
  EXPECT_EQ(rest->sample_begin(), 4u);
  EXPECT_EQ(rest->sample_end(), 16u);
  EXPECT_EQ(runs.on_result("w3", result_for(*rest)), MergeOutcome::kMerged);
  const auto tile0 = runs.next_unit("w3");  // tile 0's passes 1 to 3, skipped until now
  ASSERT_TRUE(tile0);
  EXPECT_EQ(tile0->unit_id(), 4u);
  EXPECT_EQ(tile0->sample_end(), 16u);
  EXPECT_EQ(runs.on_result("w3", result_for(*tile0)), MergeOutcome::kMerged);
  EXPECT_FALSE(runs.next_unit("w3"));

  const auto st = runs.status(id, 1);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->units_done(), 16u);
  EXPECT_EQ(st->spp_done(), 16u);
  const Image image = read_exr(dir.path() / "data" / "jobs" / id / "image.exr");
  EXPECT_TRUE(std::all_of(image.rgb.begin(), image.rgb.end(), [](float v) { return v == 0.5f; }))
      << "the late run's 9.0 was not merged";
}

TEST_F(JobManagerTest, RunsUnderATargetErrorTakeOnlyReleasedPassesAndDecideAlike) {
  // The same adaptive job, leased one unit at a time and in runs: every run stays within what
  // the rules released (the master would reject a result for anything else), and the decisions,
  // made on the same sums, are the same.
  const auto result = [](const wire::WorkUnit& unit) {
    const TileRect rect = protocol::rect_from_wire(unit.tile());
    TileResult r(rect, {unit.sample_begin(), unit.sample_end()});
    const double n = unit.sample_end() - unit.sample_begin();
    const double mean_square = unit.unit_id() % 4 == 0 ? 0.25 : 0.3;  // tile 0 is quiet
    for (auto& s : r.sum) s = to_fixed(0.5 * n);
    for (auto& s : r.sum_sq) s = to_fixed(mean_square * n);
    return protocol::result_to_wire(unit.job_id(), unit.unit_id(), r, 0.01);
  };
  std::vector<wire::JobStatus> finished;
  for (const bool with_runs : {false, true}) {
    TempDir data;
    JobStore own(data.path());
    JobManager m(own, with_runs ? long_runs(32) : JobManagerOptions{});
    wire::SubmitJob request = furnace_job(64, 16, 4);  // 4 tiles x 16 passes
    request.mutable_overrides()->set_target_error(4e-3);
    request.mutable_overrides()->set_min_passes(4);
    const std::string id = m.submit(request);
    uint32_t longest = 0;
    for (int n = 0; n < 100; ++n) {
      const auto unit = m.next_unit("w1");
      if (!unit) break;
      longest = std::max(longest, (unit->sample_end() - unit->sample_begin()) / 4);
      ASSERT_EQ(m.on_result("w1", result(*unit)), MergeOutcome::kMerged) << "lease " << n;
    }
    EXPECT_EQ(longest > 1, with_runs) << "runs cover the released minimum passes";
    const auto st = m.status(id, 1);
    ASSERT_EQ(st->state(), wire::JOB_DONE);
    finished.push_back(*st);
  }
  EXPECT_EQ(finished[0].units_done(), finished[1].units_done());
  EXPECT_EQ(finished[0].spp_mean(), finished[1].spp_mean());
  EXPECT_EQ(finished[0].tiles_converged(), finished[1].tiles_converged());
  EXPECT_EQ(finished[0].est_rel_mse(), finished[1].est_rel_mse());
  EXPECT_LT(finished[0].units_done(), 64u) << "the quiet tile stopped early";
  EXPECT_GT(finished[0].units_done(), 16u) << "the noisy tiles went on past their minimum";
}

TEST_F(JobManagerTest, ATimeLimitEndsTheJobWithWhatIsMerged) {
  wire::SubmitJob request = furnace_job(64, 16, 4);
  request.mutable_overrides()->set_time_limit_s(4.0);  // longer than a stall of a loaded machine
  const std::string id = jobs.submit(request);
  const auto unit = jobs.next_unit("w1");  // the clock starts with the first unit out
  ASSERT_TRUE(unit);
  EXPECT_EQ(jobs.on_result("w1", result_for(*unit)), MergeOutcome::kMerged);
  jobs.tick();
  EXPECT_EQ(jobs.status(id, 1)->state(), wire::JOB_RUNNING);
  test_jobs::tick_while_running(jobs, id);
  const auto st = jobs.status(id, 1);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->stop_reason(), "time limit");
  EXPECT_EQ(st->units_done(), 1u);
  EXPECT_FALSE(jobs.next_unit("w1")) << "a finished job hands out nothing";
  EXPECT_NO_THROW(jobs.image(id));
}

TEST_F(JobManagerTest, AReferenceMustFitTheImageAndIsMeasuredAgainst) {
  wire::SubmitJob request = furnace_job(8, 16, 4);
  request.set_reference_exr(constant_exr(dir, 16, 16, 0.5f));
  try {
    jobs.submit(request);
    FAIL() << "accepted a reference of the wrong size";
  } catch (const JobRejected& e) {
    EXPECT_NE(std::string(e.what()).find("16x16"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("32x32"), std::string::npos) << e.what();
  }
  request.set_reference_exr("not an EXR");
  EXPECT_THROW(jobs.submit(request), JobRejected);

  request.set_reference_exr(constant_exr(dir, 32, 32, 0.25f));
  const std::string id = jobs.submit(request);
  while (auto unit = jobs.next_unit("w1")) jobs.on_result("w1", result_for(*unit, 0.5));
  const auto st = jobs.status(id, 1);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  // Every value is 0.5 against 0.25: (0.25)^2 / (0.25^2 + 0.01).
  EXPECT_NEAR(st->ref_rel_mse(), 0.0625 / 0.0725, 1e-6);
  EXPECT_NE(jobs.image(id).error_csv().find(",0.8620"), std::string::npos)
      << jobs.image(id).error_csv();
}

TEST_F(JobManagerTest, BadStoppingRulesAreRejected) {
  wire::SubmitJob request = furnace_job(8, 16, 4);
  request.mutable_overrides()->set_target_error(-1);
  EXPECT_THROW(jobs.submit(request), JobRejected);
  request.mutable_overrides()->set_target_error(std::nan(""));
  EXPECT_THROW(jobs.submit(request), JobRejected);
  request.mutable_overrides()->set_target_error(0);
  request.mutable_overrides()->set_time_limit_s(INFINITY);
  EXPECT_THROW(jobs.submit(request), JobRejected);
}

// ---------------------------------------------------------------------------------------------
// Durability: checkpoints and resuming after a master restart

/// A result whose samples vary by tile (so the error estimate, and a target error's decisions,
/// differ from tile to tile), exactly the same whenever it is made.
wire::UnitResult noisy_result_for(const wire::WorkUnit& unit) {
  const TileRect rect = protocol::rect_from_wire(unit.tile());
  TileResult r(rect, {unit.sample_begin(), unit.sample_end()});
  const double n = unit.sample_end() - unit.sample_begin();
  const double v = 0.25 + 0.01 * (rect.x0 + 3 * rect.y0);
  const double spread = 1.0 + (rect.x0 / 8 + rect.y0 / 8) % 4;
  for (size_t i = 0; i < r.sum.size(); ++i) {
    r.sum[i] = to_fixed(v * n + 1e-3 * double(i % 7) + 1e-4 * unit.unit_id());
    r.sum_sq[i] = to_fixed((spread * v * v + 0.1) * n);  // sums that samples can have
  }
  r.rays = 100 + unit.unit_id();
  return protocol::result_to_wire(unit.job_id(), unit.unit_id(), r, 0.01);
}

/// Leases and merges up to `limit` units from `worker`; returns how many were merged.
size_t merge_units(JobManager& jobs, size_t limit, const std::string& worker = "w1") {
  size_t merged = 0;
  while (merged < limit) {
    const auto unit = jobs.next_unit(worker);
    if (!unit) break;
    if (jobs.on_result(worker, noisy_result_for(*unit)) == MergeOutcome::kMerged) ++merged;
  }
  return merged;
}

/// The pixels of a job's image.
std::vector<float> pixels_of(const fs::path& data, const std::string& id) {
  return read_exr(data / "jobs" / id / "image.exr").rgb;
}

/// The same job rendered without interruption, in a data dir of its own: its final pixels.
std::vector<float> uninterrupted(const wire::SubmitJob& request,
                                 wire::JobStatus* status = nullptr) {
  TempDir other;
  JobStore other_store(other.path() / "data");
  JobManager manager(other_store);
  const std::string id = manager.submit(request);
  merge_units(manager, 100000);
  EXPECT_EQ(manager.status(id, 0)->state(), wire::JOB_DONE);
  if (status) *status = *manager.status(id, 0);
  return pixels_of(other.path() / "data", id);
}

JobManagerOptions checkpoint_every_tick() {
  JobManagerOptions o;
  o.checkpoint_interval = std::chrono::milliseconds{1};
  o.write_share = 0;
  return o;
}

void checkpoint_now(JobManager& jobs) {
  std::this_thread::sleep_for(std::chrono::milliseconds{3});
  jobs.tick();
  jobs.wait_for_checkpoints();
}

/// The rayfarm:spp attribute of a job's image, once every image handed to the writer is on disk.
std::string image_spp(JobManager& jobs, const fs::path& job_dir) {
  jobs.wait_for_images();
  return read_exr(job_dir / "image.exr").attributes.at("rayfarm:spp");
}

TEST_F(JobManagerTest, RoundsWithinTheirIntervalsLeaveTheImageAndCheckpointToTheTick) {
  // A large farm completes rounds of passes many times a second, and each image or checkpoint is
  // a pass over the whole film: a round within the intervals writes neither (the first round's
  // image excepted); they stay due, for the tick or for shutdown.
  JobManagerOptions o;
  o.image_interval = std::chrono::hours{1};
  o.checkpoint_interval = std::chrono::hours{1};
  JobManager paced(store, o);
  const std::string id = paced.submit(furnace_job(16, 8, 4));  // 16 tiles x 4 passes of 4 spp
  const fs::path job_dir = dir.path() / "data" / "jobs" / id;
  ASSERT_EQ(merge_units(paced, 16), 16u);  // the first round
  EXPECT_EQ(image_spp(paced, job_dir), "4");
  ASSERT_EQ(merge_units(paced, 16), 16u);  // the second
  paced.tick();
  EXPECT_EQ(image_spp(paced, job_dir), "4") << "the image rewritten within its interval";
  paced.wait_for_checkpoints();
  EXPECT_FALSE(fs::exists(job_dir / "checkpoint-0.bin")) << "checkpointed within its interval";
  // What is due is written at shutdown.
  EXPECT_EQ(paced.shutdown(), 1u);
  EXPECT_EQ(image_spp(paced, job_dir), "8");
  EXPECT_TRUE(fs::exists(job_dir / "checkpoint-0.bin"));
}

TEST_F(JobManagerTest, RoundsAfterTheirIntervalsWriteTheImageAndCheckpointThemselves) {
  JobManagerOptions o;
  o.image_interval = std::chrono::milliseconds{1};
  o.checkpoint_interval = std::chrono::milliseconds{1};
  o.write_share = 0;  // the intervals as given, however long a write takes
  JobManager paced(store, o);
  const std::string id = paced.submit(furnace_job(16, 8, 4));
  const fs::path job_dir = dir.path() / "data" / "jobs" / id;
  for (const std::string spp : {"4", "8"}) {
    std::this_thread::sleep_for(std::chrono::milliseconds{3});  // the intervals are up
    ASSERT_EQ(merge_units(paced, 16), 16u);                      // a round, and no tick
    EXPECT_EQ(image_spp(paced, job_dir), spp);
  }
  paced.wait_for_checkpoints();
  EXPECT_TRUE(fs::exists(job_dir / "checkpoint-0.bin"));
  EXPECT_TRUE(fs::exists(job_dir / "checkpoint-1.bin"));
}

TEST_F(JobManagerTest, WritesThatCostMoreThanTheirShareStretchTheirIntervals) {
  // The same rounds with a write share so small that any measured cost stretches the intervals
  // past the test: after the first image and checkpoint, neither is written again until the end.
  JobManagerOptions o;
  o.image_interval = std::chrono::milliseconds{1};
  o.checkpoint_interval = std::chrono::milliseconds{1};
  o.write_share = 1e-9;
  JobManager paced(store, o);
  const std::string id = paced.submit(furnace_job(16, 8, 4));
  const fs::path job_dir = dir.path() / "data" / "jobs" / id;
  for (int round = 0; round < 2; ++round) {
    std::this_thread::sleep_for(std::chrono::milliseconds{3});  // the given intervals are up
    ASSERT_EQ(merge_units(paced, 16), 16u);
    EXPECT_EQ(image_spp(paced, job_dir), "4") << "round " << round;
    paced.wait_for_checkpoints();
    paced.tick();
  }
  EXPECT_TRUE(fs::exists(job_dir / "checkpoint-0.bin"));
  EXPECT_FALSE(fs::exists(job_dir / "checkpoint-1.bin")) << "the second checkpoint is not due";
  EXPECT_EQ(merge_units(paced, 32), 32u);  // the end: the final image is always written
  EXPECT_EQ(image_spp(paced, job_dir), "16");
}

TEST_F(JobManagerTest, AJobResumesFromItsCheckpointAndEndsBitIdentical) {
  const wire::SubmitJob request = furnace_job(16, 8, 4);  // 16 tiles x 4 passes = 64 units
  const std::vector<float> expected = uninterrupted(request);

  JobManager first(store, checkpoint_every_tick());
  const std::string id = first.submit(request);
  EXPECT_EQ(merge_units(first, 23), 23u);
  checkpoint_now(first);
  // Merged after the checkpoint, and units leased when the master dies: rendered again later.
  merge_units(first, 5);
  ASSERT_TRUE(first.next_unit("w2"));
  EXPECT_TRUE(fs::exists(dir.path() / "data" / "jobs" / id / "checkpoint-0.bin"));

  JobStore store2(dir.path() / "data");
  JobManager resumed(store2);
  EXPECT_EQ(resumed.recover(), 1u);
  auto st = resumed.status(id, 0);
  EXPECT_EQ(st->state(), wire::JOB_RUNNING);
  EXPECT_EQ(st->units_done(), 23u);
  EXPECT_EQ(st->passes_done(), 1u);
  EXPECT_GT(st->elapsed_seconds(), 0.0);
  // A unit merged before the checkpoint is a duplicate now; nothing is merged twice.
  const auto next = resumed.next_unit("w3");
  ASSERT_TRUE(next);
  EXPECT_EQ(next->unit_id(), 23u) << "the first unit not merged at the checkpoint";
  wire::WorkUnit old = *next;
  old.set_unit_id(0);
  old.set_sample_begin(0);
  old.set_sample_end(4);
  *old.mutable_tile() = protocol::rect_to_wire({0, 0, 8, 8});
  EXPECT_EQ(resumed.on_result("w3", noisy_result_for(old)), MergeOutcome::kDuplicate);
  EXPECT_EQ(resumed.on_result("w3", noisy_result_for(*next)), MergeOutcome::kMerged);
  merge_units(resumed, 1000, "w3");
  st = resumed.status(id, 0);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->units_done(), 64u);
  EXPECT_EQ(pixels_of(dir.path() / "data", id), expected) << "not bit-identical";
  resumed.wait_for_checkpoints();
  EXPECT_FALSE(fs::exists(dir.path() / "data" / "jobs" / id / "checkpoint-0.bin"))
      << "a finished job keeps no checkpoint";
  // The error record continued across the restart: one row per pass and the final one.
  const std::string csv = read_file(dir.path() / "data" / "jobs" / id / "error.csv");
  EXPECT_GE(std::count(csv.begin(), csv.end(), '\n'), 5) << csv;
}

TEST_F(JobManagerTest, ATargetErrorJobResumesWithItsPlannersDecisions) {
  wire::SubmitJob request = furnace_job(64, 8, 4);  // 16 tiles x 16 passes
  request.mutable_overrides()->set_target_error(0.05);
  request.mutable_overrides()->set_min_passes(2);
  wire::JobStatus reference;
  const std::vector<float> expected = uninterrupted(request, &reference);
  ASSERT_EQ(reference.stop_reason(), "target error");
  ASSERT_LT(reference.units_done(), 256u) << "some tiles must stop early";
  ASSERT_GT(reference.units_done(), 32u) << "some tiles must need more than the minimum";

  // Interrupted twice, at different points.
  std::string id;
  for (size_t cut : {size_t{40}, size_t{25}}) {
    JobStore s(dir.path() / "data");
    JobManager manager(s, checkpoint_every_tick());
    if (id.empty()) {
      id = manager.submit(request);
    } else {
      ASSERT_EQ(manager.recover(), 1u);
    }
    merge_units(manager, cut);
    checkpoint_now(manager);
  }
  JobStore s(dir.path() / "data");
  JobManager last(s);
  ASSERT_EQ(last.recover(), 1u);
  EXPECT_EQ(last.status(id, 0)->units_done(), 65u);
  merge_units(last, 100000);
  const auto st = last.status(id, 0);
  EXPECT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->stop_reason(), "target error");
  EXPECT_EQ(st->units_done(), reference.units_done());
  EXPECT_EQ(st->tiles_converged(), reference.tiles_converged());
  EXPECT_EQ(pixels_of(dir.path() / "data", id), expected) << "not bit-identical";
}

TEST_F(JobManagerTest, ACorruptCheckpointFallsBackToThePreviousOneOrToTheStart) {
  const wire::SubmitJob request = furnace_job(16, 8, 4);
  const std::vector<float> expected = uninterrupted(request);
  JobManager first(store, checkpoint_every_tick());
  const std::string id = first.submit(request);
  merge_units(first, 10);
  checkpoint_now(first);
  // The interval is up by the round that completes at 16: a checkpoint there, and one at 20.
  std::this_thread::sleep_for(std::chrono::milliseconds{3});
  merge_units(first, 10);
  checkpoint_now(first);
  const fs::path job_dir = dir.path() / "data" / "jobs" / id;
  const Checkpoint c0 = read_checkpoint(checkpoint_path(job_dir, 0));
  const Checkpoint c1 = read_checkpoint(checkpoint_path(job_dir, 1));
  const int newest = c0.sequence > c1.sequence ? 0 : 1;
  const Checkpoint& older = newest == 0 ? c1 : c0;
  const uint64_t older_units = std::count(older.merged.begin(), older.merged.end(), 1);
  EXPECT_EQ(std::max(c0.sequence, c1.sequence), 3u);
  EXPECT_EQ(older_units, 16u);
  {
    // Flip one byte in the middle of the newest.
    std::fstream f(checkpoint_path(job_dir, newest),
                   std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(2000);
    f.put('\x5a');
  }
  {
    JobStore s(dir.path() / "data");
    JobManager resumed(s);
    ASSERT_EQ(resumed.recover(), 1u);
    EXPECT_EQ(resumed.status(id, 0)->units_done(), older_units) << "the previous checkpoint";
  }
  // Both broken (the older one truncated): from the start.
  fs::resize_file(checkpoint_path(job_dir, 1 - newest), 100);
  JobStore s(dir.path() / "data");
  JobManager restarted(s);
  ASSERT_EQ(restarted.recover(), 1u);
  EXPECT_EQ(restarted.status(id, 0)->units_done(), 0u);
  EXPECT_EQ(restarted.status(id, 0)->state(), wire::JOB_QUEUED);
  merge_units(restarted, 1000);
  EXPECT_EQ(restarted.status(id, 0)->state(), wire::JOB_DONE);
  EXPECT_EQ(pixels_of(dir.path() / "data", id), expected);
}

TEST_F(JobManagerTest, ShutdownCheckpointsEveryRunningJob) {
  // Priorities keep the jobs from sharing the workers: a first, then b, then c.
  const auto with_priority = [](wire::SubmitJob request, int32_t priority) {
    request.set_priority(priority);
    return request;
  };
  const std::string a = jobs.submit(with_priority(furnace_job(16, 8, 4), 2));
  const std::string b = jobs.submit(with_priority(furnace_job(8, 8, 4), 1));
  const std::string c = jobs.submit(furnace_job(8, 8, 4));  // queued: nothing to checkpoint
  merge_units(jobs, 70);                                    // all of a (64) and 6 of b
  EXPECT_EQ(jobs.status(a, 0)->state(), wire::JOB_DONE);
  EXPECT_EQ(jobs.shutdown(), 1u);
  JobStore s(dir.path() / "data");
  JobManager resumed(s);
  EXPECT_EQ(resumed.recover(), 2u);  // b resumed, c queued again
  EXPECT_EQ(resumed.status(b, 0)->units_done(), 6u);
  EXPECT_EQ(resumed.status(a, 0)->state(), wire::JOB_DONE);
  EXPECT_EQ(resumed.status(c, 0)->state(), wire::JOB_QUEUED);
  EXPECT_FALSE(fs::exists(dir.path() / "data" / "jobs" / c / "checkpoint-0.bin"));
}

TEST_F(JobManagerTest, TheRecordIsOnDiskBeforeTheJobIsAccepted) {
  const std::string id = jobs.submit(furnace_job(4, 16, 4));
  // What a master killed right after answering finds: the record and the bundle.
  JobStore s(dir.path() / "data");
  const auto records = s.load_records();
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].spec.id, id);
  EXPECT_TRUE(s.load_bundle(id));
}

}  // namespace
}  // namespace rayfarm::master
