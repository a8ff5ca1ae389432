// A job's record survives a master restart in every state it can be in: queued, running,
// cancelled before or during its first pass, failed, done (with and without a target error or a
// reference). A figure that is not finite is stored as unknown, never as something the next
// master cannot read; a record that cannot be read is listed with its cause, never dropped.
// And the figures status shows are the job's real ones: passes of a finished adaptive job, an ETA
// that counts down instead of swinging with each round's estimate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>

#include <nlohmann/json.hpp>

#include "common/bundle/bundle.h"
#include "common/image/exr.h"
#include "common/protocol/convert.h"
#include "master/eta.h"
#include "master/job_manager.h"
#include "tests/master/job_requests.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;
using testing::read_file;
using testing::TempDir;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// The bundled furnace (32x32) with these overrides.
wire::SubmitJob furnace(uint32_t spp, uint32_t tile, uint32_t pass_spp) {
  return test_jobs::furnace_job(spp, tile, pass_spp);
}

/// A result of the right shape for `unit`; sample i of a pixel is worth `value` + i % 2 (so
/// that the image has variance, and its estimated error is a number).
wire::UnitResult result(const wire::WorkUnit& unit, double value = 0.5) {
  const TileRect rect = protocol::rect_from_wire(unit.tile());
  TileResult r(rect, {unit.sample_begin(), unit.sample_end()});
  double sum = 0, sum_sq = 0;
  for (uint32_t i = unit.sample_begin(); i < unit.sample_end(); ++i) {
    const double v = value + (i % 2);
    sum += v;
    sum_sq += v * v;
  }
  for (auto& s : r.sum) s = to_fixed(sum);
  for (auto& s : r.sum_sq) s = to_fixed(sum_sq);
  return protocol::result_to_wire(unit.job_id(), unit.unit_id(), r, 0.01);
}

std::string exr_bytes(const TempDir& dir, uint32_t size, float value) {
  Image image;
  image.width = image.height = size;
  image.rgb.assign(size_t{size} * size * 3, value);
  const fs::path path = dir.path() / "reference.exr";
  write_exr(path, image);
  return read_file(path);
}

JobRecord sample_record(const std::string& id, wire::JobState state) {
  JobRecord r;
  r.spec.id = id;
  r.spec.name = "furnace " + id;
  r.spec.bundle_hash = "abc";
  r.spec.scene_path = "scene.json";
  r.spec.film = {32, 32};
  r.spec.tile_size = 16;
  r.spec.pass_spp = 4;
  r.spec.settings.spp = 64;
  r.spec.stop.target_error = 0.01;
  r.spec.submitted_unix_ms = 1234;
  r.state = state;
  return r;
}

// ---------------------------------------------------------------------------------------------
// The store

TEST(JobStoreRecords, EveryStateAndNonFiniteFiguresSurviveASaveAndALoad) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  const std::vector<wire::JobState> states{wire::JOB_QUEUED, wire::JOB_RUNNING, wire::JOB_DONE,
                                           wire::JOB_FAILED, wire::JOB_CANCELLED};
  std::map<std::string, JobRecord> saved;
  for (size_t i = 0; i < states.size(); ++i) {
    JobRecord r = sample_record(store.allocate_id(), states[i]);
    r.est_rel_mse = i % 2 ? kNaN : 0.125;  // a first pass of one sample has no estimate
    r.ref_rel_mse = i % 2 ? 0.5 : kInf;
    r.spp_mean = i % 3 ? 3.5 : kNaN;
    r.elapsed_seconds = 2.0 + static_cast<double>(i);
    r.passes_done = static_cast<uint32_t>(i);
    r.spec.settings.clamp = i % 2 ? 0.f : 2.5f;
    r.stop_reason = i ? "cancelled" : "";
    r.error = i == 3 ? "unit 0 failed" : "";
    r.priority = static_cast<int32_t>(i % 2 ? -100 + i : 100 - i);
    r.paused = i % 2 == 1;
    if (i % 2 == 0) r.spec.frame = int64_t(i) * 7 - 10;  // negative frames too
    store.save_record(r);
    saved[r.spec.id] = r;
  }
  const std::vector<JobRecord> loaded = store.load_records();
  ASSERT_EQ(loaded.size(), saved.size());
  for (const JobRecord& r : loaded) {
    const JobRecord& s = saved.at(r.spec.id);
    EXPECT_FALSE(r.unreadable) << r.error;
    EXPECT_EQ(r.state, s.state);
    EXPECT_EQ(r.spec.name, s.spec.name);
    EXPECT_EQ(r.error, s.error);
    EXPECT_EQ(r.stop_reason, s.stop_reason);
    EXPECT_EQ(r.passes_done, s.passes_done);
    EXPECT_EQ(r.priority, s.priority);
    EXPECT_EQ(r.spec.frame, s.spec.frame);
    // Only a queued or running job is paused; an ended one reads as not paused.
    EXPECT_EQ(r.paused, s.paused && (s.state == wire::JOB_QUEUED || s.state == wire::JOB_RUNNING));
    EXPECT_EQ(r.elapsed_seconds, s.elapsed_seconds);
    EXPECT_EQ(r.spec.stop.target_error, s.spec.stop.target_error);
    EXPECT_EQ(r.spec.settings.clamp, s.spec.settings.clamp);
    // Finite figures come back exactly; the others as unknown (-1, or 0 for a mean).
    EXPECT_EQ(r.est_rel_mse, std::isfinite(s.est_rel_mse) ? s.est_rel_mse : -1.0);
    EXPECT_EQ(r.ref_rel_mse, std::isfinite(s.ref_rel_mse) ? s.ref_rel_mse : -1.0);
    EXPECT_EQ(r.spp_mean, std::isfinite(s.spp_mean) ? s.spp_mean : 0.0);
  }
}

TEST(JobStoreRecords, NullFiguresWrittenByAnEarlierMasterReadAsUnknown) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobRecord r = sample_record(store.allocate_id(), wire::JOB_CANCELLED);
  r.est_rel_mse = 0.25;
  store.save_record(r);
  const fs::path file = store.job_dir(r.spec.id) / "job.json";
  nlohmann::json j = nlohmann::json::parse(read_file(file));
  j["est_rel_mse"] = nullptr;  // what nlohmann writes for NaN
  j["ref_rel_mse"] = nullptr;
  j["elapsed_seconds"] = nullptr;
  std::ofstream(file) << j.dump(2);
  const auto loaded = store.load_records();
  ASSERT_EQ(loaded.size(), 1u);
  EXPECT_FALSE(loaded[0].unreadable) << loaded[0].error;
  EXPECT_EQ(loaded[0].state, wire::JOB_CANCELLED);
  EXPECT_EQ(loaded[0].est_rel_mse, -1.0);
  EXPECT_EQ(loaded[0].ref_rel_mse, -1.0);
  EXPECT_EQ(loaded[0].elapsed_seconds, 0.0);
}

TEST(JobStoreRecords, ARecordThatCannotBeReadIsReturnedWithItsCause) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  const JobRecord good = sample_record(store.allocate_id(), wire::JOB_DONE);
  store.save_record(good);
  struct Bad {
    std::string text, cause;
  };
  nlohmann::json no_spp = nlohmann::json::parse(
      read_file(store.job_dir(good.spec.id) / "job.json"));
  no_spp.erase("spp");
  nlohmann::json bad_state = no_spp;
  bad_state["spp"] = 4;
  bad_state["state"] = "sleeping";
  nlohmann::json text_figure = bad_state;
  text_figure["state"] = "done";
  text_figure["est_rel_mse"] = "small";
  std::vector<Bad> bad{{"{ \"id\": ", "parse"},
                       {no_spp.dump(), "spp"},
                       {bad_state.dump(), "sleeping"},
                       {text_figure.dump(), "est_rel_mse"}};
  // Priorities out of range, even past int32's or int64's range, and of the wrong type.
  nlohmann::json good_json = text_figure;
  good_json["est_rel_mse"] = 0.5;
  for (const nlohmann::json& priority :
       {nlohmann::json(101), nlohmann::json(-101), nlohmann::json(4294967297LL),
        nlohmann::json(18446744073709551611ULL), nlohmann::json("high"), nlohmann::json(1.5)}) {
    nlohmann::json with = good_json;
    with["priority"] = priority;
    bad.push_back({with.dump(), "priority"});
  }
  // Frames beyond +-1e9, or not integers.
  for (const nlohmann::json& frame :
       {nlohmann::json(1000000001), nlohmann::json(-1000000001), nlohmann::json(1.5),
        nlohmann::json(18446744073709551611ULL), nlohmann::json("12")}) {
    nlohmann::json with = good_json;
    with["frame"] = frame;
    bad.push_back({with.dump(), "frame"});
  }
  nlohmann::json text_paused = good_json;
  text_paused["paused"] = "yes";
  bad.push_back({text_paused.dump(), "paused"});
  std::vector<std::string> ids;
  for (const Bad& b : bad) {
    const std::string id = store.allocate_id();
    std::ofstream(store.job_dir(id) / "job.json") << b.text;
    ids.push_back(id);
  }
  const auto loaded = store.load_records();
  ASSERT_EQ(loaded.size(), 1 + bad.size());
  EXPECT_FALSE(loaded[0].unreadable);
  EXPECT_EQ(loaded[0].spec.id, good.spec.id);
  for (size_t i = 0; i < bad.size(); ++i) {
    const JobRecord& r = loaded[i + 1];
    EXPECT_TRUE(r.unreadable);
    EXPECT_EQ(r.spec.id, ids[i]);
    EXPECT_EQ(r.state, wire::JOB_STATE_UNSPECIFIED);
    EXPECT_NE(r.error.find((store.job_dir(ids[i]) / "job.json").string()), std::string::npos)
        << r.error;
    EXPECT_NE(r.error.find(bad[i].cause), std::string::npos) << r.error;
  }
  // An unreadable record is never written over.
  EXPECT_THROW(store.save_record(loaded[1]), std::logic_error);
}

// ---------------------------------------------------------------------------------------------
// The master's jobs across a restart

class JobRecordsTest : public ::testing::Test {
 protected:
  TempDir dir;
  JobStore store{dir.path() / "data"};
  JobManager jobs{store};

  void fail_unit(const std::string& id) {
    for (const std::string w : {"f1", "f2", "f3"}) {
      const auto unit = jobs.next_unit(w);
      ASSERT_TRUE(unit);
      ASSERT_EQ(unit->job_id(), id);
      wire::UnitFailed failed;
      failed.set_job_id(id);
      failed.set_unit_id(unit->unit_id());
      failed.set_reason("scene does not load on " + w);
      jobs.on_unit_failed(w, failed);
    }
  }
};

TEST_F(JobRecordsTest, EveryStateAJobCanBeInSurvivesAMasterRestart) {
  // Each job runs alone, so that the units handed out are its own.
  // Cancelled during its first pass: one sample per pixel, no error estimate yet.
  const std::string cancelled_first = jobs.submit(furnace(8, 16, 1));
  const auto first = jobs.next_unit("w1");
  ASSERT_TRUE(first);
  ASSERT_EQ(jobs.on_result("w1", result(*first)), MergeOutcome::kMerged);
  ASSERT_EQ(jobs.cancel(cancelled_first), std::optional(wire::JOB_CANCELLED));
  // Cancelled before it started.
  const std::string cancelled_queued = jobs.submit(furnace(8, 16, 4));
  jobs.cancel(cancelled_queued);
  // Failed.
  const std::string failed = jobs.submit(furnace(8, 16, 4));
  fail_unit(failed);
  // Done: every sample; to a target error; against a reference.
  const std::string done = jobs.submit(furnace(8, 16, 4));
  while (auto unit = jobs.next_unit("w1")) jobs.on_result("w1", result(*unit));
  wire::SubmitJob targeted = furnace(64, 16, 4);
  targeted.mutable_overrides()->set_target_error(10.0);  // met after the minimum passes
  targeted.mutable_overrides()->set_min_passes(2);
  const std::string done_target = jobs.submit(targeted);
  while (auto unit = jobs.next_unit("w1")) jobs.on_result("w1", result(*unit));
  wire::SubmitJob referenced = furnace(8, 16, 4);
  referenced.set_reference_exr(exr_bytes(dir, 32, 0.75f));
  const std::string done_reference = jobs.submit(referenced);
  while (auto unit = jobs.next_unit("w1")) jobs.on_result("w1", result(*unit));
  // Cancelled in its second pass, with a reference and a target.
  wire::SubmitJob both = furnace(64, 16, 4);
  both.set_reference_exr(exr_bytes(dir, 32, 0.75f));
  both.mutable_overrides()->set_target_error(1e-9);
  const std::string cancelled_later = jobs.submit(both);
  for (int i = 0; i < 6; ++i) {
    const auto unit = jobs.next_unit("w1");
    ASSERT_TRUE(unit);
    jobs.on_result("w1", result(*unit));
  }
  jobs.cancel(cancelled_later);
  // Running in its second pass, and queued.
  const std::string running = jobs.submit(furnace(64, 16, 4));
  for (int i = 0; i < 5; ++i) {
    const auto unit = jobs.next_unit("w1");
    ASSERT_TRUE(unit);
    jobs.on_result("w1", result(*unit));
  }
  ASSERT_TRUE(jobs.next_unit("w1"));
  jobs.shutdown();
  const std::string queued = jobs.submit(furnace(8, 16, 4));

  const std::map<std::string, wire::JobState> expected{
      {cancelled_first, wire::JOB_CANCELLED}, {cancelled_queued, wire::JOB_CANCELLED},
      {failed, wire::JOB_FAILED},             {done, wire::JOB_DONE},
      {done_target, wire::JOB_DONE},          {done_reference, wire::JOB_DONE},
      {cancelled_later, wire::JOB_CANCELLED}, {running, wire::JOB_RUNNING},
      {queued, wire::JOB_QUEUED}};
  std::map<std::string, wire::JobStatus> before;
  for (const auto& st : jobs.list(1)) before[st.job_id()] = st;
  ASSERT_EQ(before.size(), expected.size());
  for (const auto& [id, state] : expected) EXPECT_EQ(before[id].state(), state) << id;
  EXPECT_GT(before[done_reference].ref_rel_mse(), 0.0);
  EXPECT_EQ(before[done_target].stop_reason(), "target error");

  JobStore store2(dir.path() / "data");
  JobManager restarted(store2);
  EXPECT_EQ(restarted.recover(), 2u);  // running and queued
  std::map<std::string, wire::JobStatus> after;
  for (const auto& st : restarted.list(1)) after[st.job_id()] = st;
  ASSERT_EQ(after.size(), expected.size());
  for (const auto& [id, state] : expected) {
    const wire::JobStatus& a = after[id];
    const wire::JobStatus& b = before[id];
    SCOPED_TRACE(id);
    if (state == wire::JOB_RUNNING) {
      EXPECT_EQ(a.state(), wire::JOB_RUNNING);
      EXPECT_GE(a.units_done(), 5u);  // resumed from its checkpoint
      continue;
    }
    EXPECT_EQ(a.state(), state);
    EXPECT_EQ(a.error(), b.error());
    EXPECT_EQ(a.stop_reason(), b.stop_reason());
    EXPECT_EQ(a.units_done(), b.units_done());
    EXPECT_EQ(a.passes_done(), b.passes_done());
    EXPECT_EQ(a.spp_done(), b.spp_done());
    EXPECT_DOUBLE_EQ(a.spp_mean(), b.spp_mean());
    EXPECT_EQ(a.tiles_converged(), b.tiles_converged());
    if (std::isfinite(b.est_rel_mse())) {
      EXPECT_DOUBLE_EQ(a.est_rel_mse(), b.est_rel_mse());
    } else {
      EXPECT_LT(a.est_rel_mse(), 0.0) << "a figure that is not a number reads back as unknown";
    }
    EXPECT_DOUBLE_EQ(a.ref_rel_mse(), b.ref_rel_mse());
  }
  // The queued job still runs to its end after the restart.
  while (auto unit = restarted.next_unit("w1")) restarted.on_result("w1", result(*unit));
  EXPECT_EQ(restarted.status(queued, 1)->state(), wire::JOB_DONE);
}

TEST_F(JobRecordsTest, AJobWhoseRecordCannotBeReadIsListedWithTheCause) {
  const std::string done = jobs.submit(furnace(4, 32, 4));
  while (auto unit = jobs.next_unit("w1")) jobs.on_result("w1", result(*unit));
  const std::string broken = jobs.submit(furnace(4, 32, 4));
  jobs.cancel(broken);
  const fs::path file = store.job_dir(broken) / "job.json";
  std::ofstream(file, std::ios::trunc) << "{\"id\": \"" << broken << "\", \"state\": ";

  JobStore store2(dir.path() / "data");
  JobManager restarted(store2);
  restarted.recover();
  const auto list = restarted.list(0);
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].job_id(), done);
  EXPECT_EQ(list[0].state(), wire::JOB_DONE);
  EXPECT_EQ(list[1].job_id(), broken);
  EXPECT_EQ(list[1].state(), wire::JOB_STATE_UNSPECIFIED);
  EXPECT_STREQ(protocol::job_state_name(list[1].state()), "unknown");
  EXPECT_NE(list[1].error().find(file.string()), std::string::npos) << list[1].error();
  // Its id is not given again, cancelling it changes nothing, and its file stays as it was.
  const std::string text = read_file(file);
  EXPECT_EQ(restarted.cancel(broken), std::optional(wire::JOB_STATE_UNSPECIFIED));
  EXPECT_NE(restarted.submit(furnace(4, 32, 4)), broken);
  EXPECT_EQ(read_file(file), text);
}

TEST_F(JobRecordsTest, AFinishedAdaptiveJobShowsThePassesItRan) {
  wire::SubmitJob request = furnace(64, 16, 4);  // 16 passes of 4 spp
  request.mutable_overrides()->set_target_error(10.0);
  request.mutable_overrides()->set_min_passes(3);
  const std::string id = jobs.submit(request);
  while (auto unit = jobs.next_unit("w1")) jobs.on_result("w1", result(*unit));
  const auto st = jobs.status(id, 1);
  ASSERT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->stop_reason(), "target error");
  EXPECT_EQ(st->passes_total(), 16u);
  // Every tile stopped after the minimum: that many passes cover the image, no fewer, no more.
  EXPECT_EQ(st->passes_done(), 3u);
  EXPECT_EQ(st->spp_done(), 12u);
  JobStore store2(dir.path() / "data");
  JobManager restarted(store2);
  restarted.recover();
  EXPECT_EQ(restarted.status(id, 1)->passes_done(), 3u);
}

TEST_F(JobRecordsTest, RemoveTakesOnlyFinishedJobsAndKeepsServingASharedBundle) {
  const std::string first = jobs.submit(furnace(4, 32, 4));
  const std::string second = jobs.submit(furnace(4, 32, 4));  // the same scene, the same bundle
  try {
    jobs.remove(first);
    FAIL() << "removed a queued job";
  } catch (const JobRejected& e) {
    EXPECT_NE(std::string(e.what()).find("cancel it first"), std::string::npos) << e.what();
  }
  EXPECT_THROW(jobs.remove("j4242"), JobRejected);
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  ASSERT_EQ(unit->job_id(), first);
  jobs.on_result("w1", result(*unit));
  ASSERT_EQ(jobs.status(first, 1)->state(), wire::JOB_DONE);
  jobs.remove(first);
  EXPECT_FALSE(jobs.status(first, 1));
  EXPECT_FALSE(fs::exists(store.job_dir(first)));
  // The other job's units still find their bundle, and the ids go on.
  EXPECT_TRUE(jobs.bundle(unit->bundle_hash()));
  while (auto u = jobs.next_unit("w1")) jobs.on_result("w1", result(*u));
  EXPECT_EQ(jobs.status(second, 1)->state(), wire::JOB_DONE);
  EXPECT_NE(jobs.submit(furnace(4, 32, 4)), first);
  // After a restart too.
  JobStore store2(dir.path() / "data");
  JobManager restarted(store2);
  restarted.recover();
  EXPECT_EQ(restarted.list(0).size(), 2u);
}

TEST_F(JobRecordsTest, RetryRunsAFailedJobAgainToTheSameImageAsAFreshOne) {
  const std::string fresh = jobs.submit(furnace(8, 16, 4));
  while (auto unit = jobs.next_unit("w1")) jobs.on_result("w1", result(*unit));
  const std::string failed = jobs.submit(furnace(8, 16, 4));
  fail_unit(failed);
  ASSERT_EQ(jobs.status(failed, 1)->state(), wire::JOB_FAILED);
  EXPECT_THROW(jobs.retry(fresh), JobRejected) << "a done job is not retried";
  EXPECT_EQ(jobs.retry(failed), wire::JOB_QUEUED);
  const auto queued = jobs.status(failed, 1);
  EXPECT_EQ(queued->state(), wire::JOB_QUEUED);
  EXPECT_TRUE(queued->error().empty()) << queued->error();
  EXPECT_EQ(queued->units_done(), 0u);
  while (auto unit = jobs.next_unit("w1")) jobs.on_result("w1", result(*unit));
  const auto done = jobs.status(failed, 1);
  EXPECT_EQ(done->state(), wire::JOB_DONE);
  EXPECT_EQ(done->units_done(), jobs.status(fresh, 1)->units_done());
  const Image a = read_exr(store.image_path(fresh)), b = read_exr(store.image_path(failed));
  EXPECT_EQ(a.rgb, b.rgb);
}

TEST_F(JobRecordsTest, AJobsTimesAndLogSurviveARestartAndARetryAndTheLogStaysBounded) {
  const std::string id = jobs.submit(furnace(8, 16, 4));
  const auto queued = jobs.status(id, 1);
  EXPECT_GT(queued->submitted_unix_ms(), 0);
  EXPECT_EQ(queued->started_unix_ms(), 0) << "not started before its first unit goes out";
  fail_unit(id);  // three workers fail the same unit: the job fails
  const auto failed = jobs.status(id, 1);
  ASSERT_EQ(failed->state(), wire::JOB_FAILED);
  EXPECT_GE(failed->started_unix_ms(), failed->submitted_unix_ms());
  EXPECT_GE(failed->finished_unix_ms(), failed->started_unix_ms());
  const auto log = jobs.detail(id, 1)->log();
  auto has = [](const auto& lines, const std::string& level, const std::string& text) {
    return std::any_of(lines.begin(), lines.end(), [&](const wire::JobLogLine& l) {
      return l.level() == level && l.text().find(text) != std::string::npos;
    });
  };
  EXPECT_TRUE(has(log, "info", "accepted: scene")) << jobs.detail(id, 1)->DebugString();
  EXPECT_TRUE(has(log, "info", "started: its first unit went to"));
  // Workers are named by the hex of their id without a naming function: "f2" is 6632.
  EXPECT_TRUE(has(log, "warning", "failed on 6632: scene does not load on f2"));
  EXPECT_TRUE(has(log, "error", "failed after"));

  // A restarted master has the same times and lines; a retry keeps the history and starts anew.
  JobManager restarted(store);
  restarted.recover();
  const auto again = restarted.detail(id, 1);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status().finished_unix_ms(), failed->finished_unix_ms());
  EXPECT_EQ(again->status().submitted_unix_ms(), failed->submitted_unix_ms());
  ASSERT_EQ(again->log_size(), log.size());
  for (int i = 0; i < log.size(); ++i) {
    EXPECT_EQ(again->log(i).SerializeAsString(), log.Get(i).SerializeAsString()) << i;
  }
  EXPECT_EQ(restarted.retry(id, "alice"), wire::JOB_QUEUED);
  const auto retried = restarted.detail(id, 1);
  EXPECT_EQ(retried->status().started_unix_ms(), 0);
  EXPECT_EQ(retried->status().finished_unix_ms(), 0);
  EXPECT_EQ(retried->status().submitted_unix_ms(), failed->submitted_unix_ms());
  EXPECT_TRUE(has(retried->log(), "error", "failed after"));
  EXPECT_TRUE(has(retried->log(), "info", "queued again by key 'alice'"));

  // Failures without end: the latest JobLog::kMaxLines lines, the rest counted.
  const auto unit = restarted.next_unit("w9");
  ASSERT_TRUE(unit);
  for (int i = 0; i < 100; ++i) {
    restarted.change(id, std::nullopt, i % 2 == 0, "bob");  // pause, resume: a line each
  }
  const auto bounded = restarted.detail(id, 1);
  EXPECT_EQ(static_cast<size_t>(bounded->log_size()), JobLog::kMaxLines);
  EXPECT_EQ(bounded->log_left_out() + bounded->log_size(),
            retried->log_left_out() + retried->log_size() + 1 + 100)
      << "the lines before, the start, and a pause or resume each";
  EXPECT_TRUE(has(bounded->log(), "info", "resumed by key 'bob'"));
}

TEST(JobLogTest, TextIsMadeUtf8AndFreeOfControlsBeforeItIsKept) {
  JobLog log;
  // Broken and overlong sequences, a surrogate, a lone continuation byte, a cut character,
  // escapes and a NUL: each bad byte a '?'; well-formed characters (2, 3 and 4 bytes) kept.
  log.add(1, "warning",
          std::string("a\xff"
                      "b\xc0\xaf"
                      "c\xed\xa0\x80"
                      "d\x80"
                      "e\x1b[31m"
                      "f") +
              '\0' + "g\xc3\xa9h\xe2\x82\xaci\xf0\x9f\x8e\xa8j\xe2\x82");
  ASSERT_EQ(log.lines.size(), 1u);
  EXPECT_EQ(log.lines[0].text, "a?b??c???d?e?[31mf?g\xc3\xa9h\xe2\x82\xaci\xf0\x9f\x8e\xa8j??");
  // Such a record is saved and read back (JSON takes UTF-8 only).
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobRecord r = sample_record(store.allocate_id(), wire::JOB_RUNNING);
  r.log = log;
  EXPECT_NO_THROW(store.save_record(r));
  const auto loaded = store.load_records();
  ASSERT_EQ(loaded.size(), 1u);
  EXPECT_EQ(loaded[0].log, log);
}

TEST_F(JobRecordsTest, ALogLineOfARunningJobOutlivesARestart) {
  const std::string id = jobs.submit(furnace(8, 16, 4));
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  wire::UnitFailed failed;
  failed.set_job_id(id);
  failed.set_unit_id(unit->unit_id());
  failed.set_reason("the GPU fell off the bus");
  ASSERT_TRUE(jobs.on_unit_failed("w1", failed));
  jobs.shutdown();  // the master stops while the job runs
  JobManager restarted(store);
  restarted.recover();
  const auto log = restarted.detail(id, 1)->log();
  EXPECT_TRUE(std::any_of(log.begin(), log.end(), [](const wire::JobLogLine& l) {
    return l.text().find("the GPU fell off the bus") != std::string::npos;
  })) << restarted.detail(id, 1)->DebugString();
}

TEST(JobStoreRecords, AMalformedLogMakesTheRecordUnreadableNamingIt) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobRecord r = sample_record(store.allocate_id(), wire::JOB_DONE);
  // Cut where a two-byte character begins: the line stays UTF-8.
  r.log.add(5, "info", std::string(JobLog::kMaxText - 4, 'x') + "\xc3\xa9" + std::string(99, 'y'));
  store.save_record(r);
  auto loaded = store.load_records();
  ASSERT_EQ(loaded.size(), 1u);
  ASSERT_EQ(loaded[0].log.lines.size(), 1u);
  EXPECT_EQ(loaded[0].log.lines[0].text, std::string(JobLog::kMaxText - 4, 'x') + "...");
  const fs::path path = store.job_dir(r.spec.id) / "job.json";
  nlohmann::json j = nlohmann::json::parse(read_file(path));
  j["log"] = nlohmann::json::array({nlohmann::json::array({1, "info"})});
  std::ofstream(path) << j.dump();
  loaded = store.load_records();
  ASSERT_EQ(loaded.size(), 1u);
  EXPECT_TRUE(loaded[0].unreadable);
  EXPECT_NE(loaded[0].error.find("malformed log"), std::string::npos) << loaded[0].error;
}

// ---------------------------------------------------------------------------------------------
// The ETA

ErrorRow row(double t, double est) {
  ErrorRow r;
  r.time_s = t;
  r.est_rel_mse = est;
  return r;
}

TEST(Eta, WithAnErrorFallingAs1OverTTheFinishTimeDoesNotMoveBetweenRounds) {
  StopRules stop;
  stop.target_error = 1e-3;
  const double c = 0.05;  // relMSE = c / t: the target is reached at c / target = 50 s
  std::vector<ErrorRow> rows;
  for (int round = 1; round <= 8; ++round) {
    rows.push_back(row(round * 2.0, c / (round * 2.0)));
    for (double t = round * 2.0; t < round * 2.0 + 2.0; t += 0.5) {
      // Plenty of samples left: the error decides.
      const double eta = estimate_eta(stop, 1e12, 1e6, t, rows);
      EXPECT_NEAR(t + eta, c / stop.target_error, 1e-9) << "at " << t << " s";
    }
  }
}

TEST(Eta, ANoisyEstimateMovesTheFinishTimeLessThanOneRoundsEstimateWould) {
  StopRules stop;
  stop.target_error = 1e-3;
  const double c = 0.05, finish = c / stop.target_error;
  std::vector<ErrorRow> rows;
  double worst = 0.0, worst_single = 0.0;
  for (int round = 1; round <= 12; ++round) {
    const double t = round * 2.0;
    const double noise = round % 2 ? 1.4 : 0.6;  // each round's estimate 40% off either way
    rows.push_back(row(t, noise * c / t));
    const double eta = estimate_eta(stop, 1e12, 1e6, t, rows);
    const double single = estimate_eta(stop, 1e12, 1e6, t, {rows.back()});
    if (round >= 2) worst = std::max(worst, std::abs(t + eta - finish) / finish);
    worst_single = std::max(worst_single, std::abs(t + single - finish) / finish);
  }
  EXPECT_LT(worst, 0.25);
  EXPECT_LT(worst, worst_single / 2);
}

TEST(Eta, AnEstimateBelowTheTargetBeforeTheEndCountsDownInsteadOfJumpingToEverySample) {
  StopRules stop;
  stop.target_error = 1e-2;
  std::vector<ErrorRow> rows{row(1.0, 0.04), row(2.0, 0.02), row(3.0, 0.0099)};
  const double remaining_samples = 1e9, rate = 1e6;  // 1000 s for every sample
  const double eta = estimate_eta(stop, remaining_samples, rate, 3.0, rows);
  EXPECT_GE(eta, 0.0);
  EXPECT_LT(eta, 10.0);
  // Without a target, the samples decide; with a time limit, the limit when it comes first.
  EXPECT_DOUBLE_EQ(estimate_eta(StopRules{}, remaining_samples, rate, 3.0, rows), 1000.0);
  StopRules limited;
  limited.time_limit_s = 5.0;
  EXPECT_DOUBLE_EQ(estimate_eta(limited, remaining_samples, rate, 3.0, rows), 2.0);
  EXPECT_LT(estimate_eta(StopRules{}, remaining_samples, 0.0, 3.0, {}), 0.0) << "unknown";
}

}  // namespace
}  // namespace rayfarm::master
