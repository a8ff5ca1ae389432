// Sequences in the job manager, without sockets: a sequence's frames are jobs handed out in frame
// order, its status sums theirs, it survives a restart whole, and what cannot be a sequence is
// refused by name at submission (or by the queue's limit).
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <thread>

#include "common/bundle/bundle.h"
#include "common/protocol/convert.h"
#include "master/job_manager.h"
#include "master/peer_limits.h"
#include "tests/master/job_requests.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {

using test_jobs::result_for;
using testing::TempDir;

/// The bundled animation at 16x16, one unit per frame (2 spp in one pass of one tile).
wire::SubmitJob animation_job(int64_t first, int64_t last, int64_t step) {
  const PackedScene packed = pack_scene(std::filesystem::path(RAYFARM_SOURCE_DIR) / "scenes" /
                                        "animated-box" / "scene.json");
  wire::SubmitJob request;
  protocol::bundle_to_wire(packed.bundle, request.mutable_bundle());
  request.set_scene_path(packed.scene_path);
  request.set_name("shot");
  wire::JobOverrides* o = request.mutable_overrides();
  o->set_spp(2);
  o->set_tile_size(16);
  o->set_pass_spp(2);
  o->set_width(16);
  o->set_height(16);
  *request.mutable_frames() = protocol::frames_to_wire({first, last, step});
  return request;
}

/// animation_job() with the animation stretched to `frames` frames, all of them asked for.
wire::SubmitJob long_animation_job(int64_t frames) {
  wire::SubmitJob request = animation_job(1, 1, 1);
  std::string& scene = *request.mutable_bundle()->mutable_files(0)->mutable_data();
  const std::string range = "\"frames\": [1, 48]";
  const size_t at = scene.find(range);
  if (at == std::string::npos) throw std::runtime_error("the animated box's frame range moved");
  scene.replace(at, range.size(), "\"frames\": [1, " + std::to_string(frames) + "]");
  // The bundle's hash covers its files: packed again by the same code as a client's.
  Bundle bundle = protocol::bundle_from_wire(request.bundle());
  bundle = make_bundle(std::move(bundle.files));
  request.clear_bundle();
  protocol::bundle_to_wire(bundle, request.mutable_bundle());
  *request.mutable_frames() = protocol::frames_to_wire({1, frames, 1});
  return request;
}

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(JobSequences, FramesGoOutInOrderAndTheSequenceSurvivesARestart) {
  TempDir dir;
  std::string seq;
  {
    JobStore store(dir.path() / "data");
    JobManager jobs(store);
    seq = jobs.submit(animation_job(2, 7, 2), "alice");  // frames 2, 4, 6
    ASSERT_NE(jobs.owner_of(seq), nullptr);
    EXPECT_EQ(*jobs.owner_of(seq), "alice");
    const auto st = jobs.status(seq, 1);
    ASSERT_TRUE(st);
    EXPECT_EQ(st->name(), "shot");
    EXPECT_EQ(st->frames_total(), 3u);
    EXPECT_EQ(st->state(), wire::JOB_QUEUED);
    ASSERT_EQ(st->frames_size(), 3);
    EXPECT_EQ(st->frames(2).frame(), 6);
    EXPECT_EQ(st->frames(2).job_id(), seq + ".0006");
    // list(): the sequence is one line.
    const auto list = jobs.list(1);
    ASSERT_EQ(list.size(), 1u);
    EXPECT_EQ(list[0].job_id(), seq);
    EXPECT_EQ(list[0].frames_size(), 0);

    const auto unit = jobs.next_unit("w1");
    ASSERT_TRUE(unit);
    EXPECT_EQ(unit->job_id(), seq + ".0002");
    EXPECT_EQ(unit->frame(), 2);
    ASSERT_EQ(jobs.on_result("w1", result_for(*unit)), MergeOutcome::kMerged);
    test_jobs::tick_while_running(jobs, seq + ".0002");
    EXPECT_EQ(jobs.status(seq, 1)->frames_done(), 1u);
    EXPECT_EQ(jobs.status(seq, 1)->frame(), 4);  // the first frame not done
    jobs.shutdown();
  }
  JobStore store(dir.path() / "data");
  JobManager restarted(store);
  EXPECT_EQ(restarted.recover(), 2u);  // frames 4 and 6
  const auto st = restarted.status(seq, 1);
  ASSERT_TRUE(st);
  EXPECT_EQ(st->frames_done(), 1u);
  EXPECT_EQ(st->frames(0).state(), wire::JOB_DONE);
  const auto next = restarted.next_unit("w2");
  ASSERT_TRUE(next);
  EXPECT_EQ(next->frame(), 4);
  // Removing a frame alone is refused; the sequence cannot go while frames run.
  EXPECT_THROW(restarted.remove(seq + ".0002"), JobRejected);
  EXPECT_THROW(restarted.remove(seq), JobRejected);
  ASSERT_EQ(restarted.cancel(seq), wire::JOB_CANCELLED);
  restarted.remove(seq);
  EXPECT_FALSE(restarted.status(seq, 1));
  EXPECT_FALSE(std::filesystem::exists(store.job_dir(seq)));
  EXPECT_FALSE(std::filesystem::exists(store.job_dir(seq + ".0004")));
}

TEST(JobSequences, ASequenceCutShortByACrashWhileAcceptedIsRemovedAtTheRestart) {
  TempDir dir;
  std::string seq, single;
  {
    JobStore store(dir.path() / "data");
    JobManager jobs(store);
    seq = jobs.submit(animation_job(1, 3, 1));
    single = jobs.submit(test_jobs::furnace_job(2, 16, 2));
    jobs.shutdown();
    // As if the master had stopped before the last frame's record was written and the sequence
    // marked whole.
    std::filesystem::remove(store.job_dir(seq) / "sequence.json");
    std::filesystem::remove_all(store.job_dir(seq + ".0003"));
  }
  JobStore store(dir.path() / "data");
  JobManager restarted(store);
  EXPECT_EQ(restarted.recover(), 1u);  // the single job alone
  EXPECT_FALSE(restarted.status(seq, 1));
  EXPECT_FALSE(restarted.status(seq + ".0001", 1));
  EXPECT_FALSE(std::filesystem::exists(store.job_dir(seq + ".0001")));
  EXPECT_FALSE(std::filesystem::exists(store.job_dir(seq)));
  EXPECT_TRUE(restarted.status(single, 1));
}

TEST(JobSequences, APriorityIsTheSequencesAndARetryCountsItsFrames) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobManager jobs(store);
  const std::string seq = jobs.submit(animation_job(1, 4, 1));
  EXPECT_THROW(jobs.change(seq + ".0002", 5, std::nullopt), JobRejected);
  ASSERT_NE(jobs.change(seq, 5, std::nullopt), nullptr);
  EXPECT_EQ(jobs.status(seq + ".0004", 1)->priority(), 5);
  ASSERT_NE(jobs.change(seq + ".0002", std::nullopt, true), nullptr);  // one frame held
  EXPECT_TRUE(jobs.status(seq + ".0002", 1)->paused());
  EXPECT_FALSE(jobs.status(seq, 1)->paused());
  EXPECT_EQ(jobs.retry_count(seq), 0u);
  ASSERT_EQ(jobs.cancel(seq), wire::JOB_CANCELLED);
  EXPECT_EQ(jobs.retry_count(seq), 4u);
  EXPECT_EQ(jobs.retry_count(seq + ".0001"), 1u);
  EXPECT_EQ(jobs.retry_count("j9999"), 0u);
  EXPECT_EQ(jobs.retry(seq), wire::JOB_QUEUED);
  EXPECT_EQ(jobs.retry_count(seq), 0u);
}

TEST(JobSequences, WhatCannotBeASequenceIsRefusedByName) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobManager jobs(store);
  const auto expect_refused = [&](const wire::SubmitJob& request, const std::string& words) {
    try {
      jobs.submit(request);
      ADD_FAILURE() << "accepted; expected a refusal with " << words;
    } catch (const JobRejected& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  expect_refused(animation_job(40, 60, 1), "frame 60 is outside the scene's frames 1-48");
  expect_refused(animation_job(-3, 2, 1), "frame -3 is outside");
  expect_refused(animation_job(5, 1, 1), "reversed");
  expect_refused(animation_job(1, 5, -1), "step");
  wire::SubmitJob both = animation_job(1, 3, 1);
  both.set_frame(2);
  expect_refused(both, "one frame or a sequence of frames, not both");
  wire::SubmitJob reference = animation_job(1, 3, 1);
  reference.set_reference_exr("x");
  expect_refused(reference, "a sequence cannot have one");
  wire::SubmitJob extreme = animation_job(1, 3, 1);
  extreme.clear_frames();
  extreme.set_frame(INT64_MIN);
  expect_refused(extreme, "out of range");
  wire::SubmitJob no_step = animation_job(1, 3, 1);
  no_step.mutable_frames()->set_step(0);
  expect_refused(no_step, "step");
  wire::SubmitJob still = test_jobs::furnace_job(2, 16, 2);
  *still.mutable_frames() = protocol::frames_to_wire({1, 2, 1});
  expect_refused(still, "still");

  // A list of scene files, as a client that packs them itself may send it: a frame's file
  // missing from the bundle, files of two sizes, an animated file.
  const std::string box = pack_scene(std::filesystem::path(RAYFARM_SOURCE_DIR) / "scenes" /
                                     "cornell-box" / "scene.json")
                              .bundle.files.at(0)
                              .data;
  const std::string animated = animation_job(1, 1, 1).bundle().files(0).data();
  const auto list_job = [&](std::vector<BundleFile> files) {
    wire::SubmitJob request;
    protocol::bundle_to_wire(make_bundle(std::move(files)), request.mutable_bundle());
    request.set_scene_path("shots/f_%03d.json");
    *request.mutable_frames() = protocol::frames_to_wire({1, 3, 1});
    return request;
  };
  std::string wide = box;
  const std::string square = "\"film\": {\"width\": 256, \"height\": 256}";
  const size_t film = wide.find(square);
  ASSERT_NE(film, std::string::npos);
  wide.replace(film, square.size(), "\"film\": {\"width\": 64, \"height\": 32}");
  expect_refused(list_job({{"shots/f_001.json", box}, {"shots/f_003.json", box}}),
                 "frame 2's scene file 'shots/f_002.json' is not in the bundle");
  expect_refused(
      list_job({{"shots/f_001.json", box}, {"shots/f_002.json", box}, {"shots/f_003.json", wide}}),
      "shots/f_003.json is 64x32 but shots/f_001.json is");
  std::string seeded = box;
  const std::string render = "\"render\": {\"spp\": 64,";
  ASSERT_NE(seeded.find(render), std::string::npos);
  seeded.replace(seeded.find(render), render.size(), "\"render\": {\"seed\": 9, \"spp\": 64,");
  expect_refused(
      list_job(
          {{"shots/f_001.json", box}, {"shots/f_002.json", box}, {"shots/f_003.json", seeded}}),
      "shots/f_003.json's render settings differ from shots/f_001.json's");
  expect_refused(
      list_job(
          {{"shots/f_001.json", animated}, {"shots/f_002.json", box}, {"shots/f_003.json", box}}),
      "shots/f_001.json is animated");
  EXPECT_TRUE(jobs.list(0).empty());  // nothing accepted half-way
  // The same list, whole, is a sequence whose frames render their own files as stills.
  const std::string seq = jobs.submit(
      list_job({{"shots/f_001.json", box}, {"shots/f_002.json", box}, {"shots/f_003.json", box}}));
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  EXPECT_EQ(unit->job_id(), seq + ".0001");
  EXPECT_EQ(unit->scene_path(), "shots/f_001.json");
  EXPECT_FALSE(unit->has_frame());
  EXPECT_EQ(jobs.status(seq, 1)->frames_total(), 3u);
}

// A sequence's pause, priority and cancel are the sequence's, set once: each call visits a
// bounded number of jobs whatever the sequence's length, writes no frame's record, and another
// job goes on being served. (These visited every frame, writing each one's record and a log
// line.)
TEST(JobSequences, ALongSequencesChangesCostBoundedWorkPerCall) {
  // Long enough that a cancel takes many slices and a restart comes in the middle of it; the
  // bounds below do not depend on the length (100,000 frames pass them too, in minutes: most of
  // that is storing and reading back each frame's folder).
  constexpr int64_t kFrames = 5000;
  TempDir dir;
  std::string seq, other;
  const auto far_record = [&](const JobStore& store) {
    return read_text(store.job_dir(JobStore::frame_id(seq, kFrames / 2)) / "job.json");
  };
  {
    JobStore store(dir.path() / "data");
    JobManager jobs(store);
    seq = jobs.submit(long_animation_job(kFrames), "alice");
    other = jobs.submit(test_jobs::furnace_job(64, 16, 2), "bob");
    ASSERT_EQ(jobs.status(seq, 1)->frames_total(), static_cast<uint32_t>(kFrames));
    // Frame 1 starts: the sequence is the older job, and frames go in order.
    const auto first = jobs.next_unit("w1");
    ASSERT_TRUE(first);
    EXPECT_EQ(first->job_id(), seq + ".0001");
    const std::string far_before = far_record(store);
    // A bounded amount of work per call: the frames running (one here), not the sequence.
    constexpr uint64_t kBound = 16;
    const auto visits = [&](auto&& call) {
      const uint64_t before = jobs.jobs_visited();
      call();
      return jobs.jobs_visited() - before;
    };
    EXPECT_LE(visits([&] { ASSERT_NE(jobs.change(seq, std::nullopt, true), nullptr); }), kBound);
    EXPECT_TRUE(jobs.status(seq, 1)->paused());
    EXPECT_TRUE(jobs.status(JobStore::frame_id(seq, kFrames), 1)->paused());
    // Paused, the sequence gets no unit; the other job gets every one.
    for (int i = 0; i < 4; ++i) {
      const auto unit = jobs.next_unit("w" + std::to_string(i + 2));
      ASSERT_TRUE(unit);
      EXPECT_EQ(unit->job_id(), other);
    }
    EXPECT_LE(visits([&] { jobs.tick(); }), kBound);
    EXPECT_LE(visits([&] { ASSERT_NE(jobs.change(seq, 7, false), nullptr); }), kBound);
    EXPECT_FALSE(jobs.status(seq, 1)->paused());
    EXPECT_EQ(jobs.status(JobStore::frame_id(seq, kFrames), 1)->priority(), 7);
    // Raised above the other job, it is served first again.
    const auto raised = jobs.next_unit("w9");
    ASSERT_TRUE(raised);
    EXPECT_EQ(raised->job_id(), seq + ".0002");
    // No frame's record was written for any of it: the sequence's own says.
    EXPECT_EQ(far_record(store), far_before);
    EXPECT_NE(read_text(store.job_dir(seq) / "sequence.json").find("\"priority\":7"),
              std::string::npos);

    // Cancel: the answer is at once, no frame gets a unit again, and tick() ends the frames a
    // bounded slice at a time while the other job is served.
    EXPECT_LE(visits([&] { ASSERT_EQ(jobs.cancel(seq), wire::JOB_CANCELLED); }),
              JobManager::kCancelSlice);
    EXPECT_EQ(jobs.status(seq, 1)->state(), wire::JOB_CANCELLED);
    EXPECT_EQ(far_record(store), far_before);
    EXPECT_THROW(jobs.remove(seq), JobRejected);  // frames still to end
    EXPECT_THROW(jobs.change(seq, std::nullopt, true), JobRejected);
    const auto next = jobs.next_unit("w10");
    ASSERT_TRUE(next);
    EXPECT_EQ(next->job_id(), other);
    for (int i = 0; i < 3; ++i) {
      EXPECT_LE(visits([&] { jobs.tick(); }), JobManager::kCancelSlice + kBound);
    }
    // A stop part-way: the restart reads the frames left as cancelled.
    jobs.shutdown();
  }
  JobStore store(dir.path() / "data");
  JobManager restarted(store);
  EXPECT_EQ(restarted.recover(), 1u);  // the other job alone
  const auto st = restarted.status(seq, 1);
  ASSERT_TRUE(st);
  EXPECT_EQ(st->state(), wire::JOB_CANCELLED);
  EXPECT_EQ(restarted.status(JobStore::frame_id(seq, kFrames), 1)->state(), wire::JOB_CANCELLED);
  EXPECT_EQ(restarted.status(other, 1)->state(), wire::JOB_RUNNING);
  for (int i = 0; i < 3; ++i) {
    const auto unit = restarted.next_unit("w" + std::to_string(i));
    ASSERT_TRUE(unit);
    EXPECT_EQ(unit->job_id(), other);
  }
  restarted.remove(seq);
  EXPECT_FALSE(std::filesystem::exists(store.job_dir(seq)));
}

// Frames rendered one after another: the sequence's rate is its samples over its own time, not
// the sum of its frames' rates (which counted the farm's rate once per frame).
TEST(JobSequences, ASequencesRateIsItsSamplesOverItsTime) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobManager jobs(store);
  const std::string seq = jobs.submit(animation_job(1, 3, 1));
  for (int frame = 1; frame <= 3; ++frame) {
    const auto unit = jobs.next_unit("w1");
    ASSERT_TRUE(unit);
    ASSERT_EQ(unit->frame(), frame);
    // Some time on the frame, so that its own rate is finite; nothing here depends on how much.
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    // One worker, one unit a frame: the frames render one after another.
    ASSERT_EQ(jobs.on_result("w1", test_jobs::result_for(*unit)), MergeOutcome::kMerged);
  }
  const auto st = jobs.status(seq, 1);
  ASSERT_TRUE(st);
  ASSERT_EQ(st->state(), wire::JOB_DONE);
  double samples = 0, frames_seconds = 0;
  for (const auto& f : st->frames()) {
    const auto frame = jobs.status(f.job_id(), 1);
    samples += frame->spp_mean() * frame->width() * frame->height();
    frames_seconds += frame->elapsed_seconds();
  }
  EXPECT_EQ(samples, 3.0 * 16 * 16 * 2);
  ASSERT_GT(st->samples_per_second(), 0.0);
  // The frames ran one after another within the sequence's time: its rate is at most their
  // samples over their times added up, and it is its samples over its elapsed time.
  EXPECT_LE(st->samples_per_second() * frames_seconds, samples * (1 + 1e-9));
  EXPECT_NEAR(st->samples_per_second() * st->elapsed_seconds(), samples, samples * 1e-9);
}

// A sequence accepted paused and then resumed: a frame that starts afterwards runs its clock
// (a frame was held paused before it started, and the resume, which visits the started frames
// only, left it so: its time stayed 0, and a time limit never fired). A cancel ends the
// sequence's pause, so that a retry runs.
TEST(JobSequences, AFrameStartedAfterItsSequenceIsResumedRunsItsClock) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobManager jobs(store);
  wire::SubmitJob request = animation_job(1, 3, 1);
  request.set_paused(true);
  const std::string seq = jobs.submit(request);
  EXPECT_FALSE(jobs.next_unit("w1")) << "held";
  ASSERT_NE(jobs.change(seq, std::nullopt, false), nullptr);
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  EXPECT_GT(jobs.status(unit->job_id(), 1)->elapsed_seconds(), 0.0);
  EXPECT_GT(jobs.status(seq, 1)->elapsed_seconds(), 0.0);

  ASSERT_NE(jobs.change(seq, std::nullopt, true), nullptr);
  EXPECT_TRUE(jobs.status(seq, 1)->paused());
  ASSERT_EQ(jobs.cancel(seq), wire::JOB_CANCELLED);
  EXPECT_FALSE(jobs.status(seq, 1)->paused());
  jobs.retry(seq);
  EXPECT_FALSE(jobs.status(seq, 1)->paused());
  const auto again = jobs.next_unit("w2");
  ASSERT_TRUE(again) << "a retried sequence runs";
  EXPECT_EQ(again->job_id(), JobStore::frame_id(seq, 1));
}

TEST(JobSequences, EachKeyHasABudgetOfChanges) {
  ChangeBudget budget;
  const auto t0 = ChangeBudget::Clock::now();
  for (int i = 0; i < static_cast<int>(ChangeBudget::kBurst); ++i) {
    ASSERT_TRUE(budget.take("mallory", t0)) << i;
  }
  EXPECT_FALSE(budget.take("mallory", t0));
  EXPECT_TRUE(budget.take("alice", t0)) << "another key's budget is its own";
  // A second later, a second's worth more.
  const auto t1 = t0 + std::chrono::seconds(1);
  for (int i = 0; i < static_cast<int>(ChangeBudget::kPerSecond); ++i) {
    ASSERT_TRUE(budget.take("mallory", t1)) << i;
  }
  EXPECT_FALSE(budget.take("mallory", t1));
  // The job manager's, with the refusal a client is told.
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobManager jobs(store);
  for (int i = 0; i < static_cast<int>(ChangeBudget::kBurst); ++i) {
    ASSERT_FALSE(jobs.take_change("mallory", t0)) << i;
  }
  const auto refusal = jobs.take_change("mallory", t0);
  ASSERT_TRUE(refusal);
  EXPECT_NE(refusal->find("too many changes from this key: at most 10 a second"),
            std::string::npos)
      << *refusal;
  EXPECT_FALSE(jobs.take_change("alice", t0));
}

TEST(JobSequences, TheQueueLimitCountsEveryFrame) {
  Limits limits;
  limits.max_queued_jobs = 10;
  EXPECT_FALSE(check_queue(5, limits, 5));
  const auto full = check_queue(6, limits, 5);
  ASSERT_TRUE(full);
  EXPECT_NE(full->find("queue is full"), std::string::npos) << *full;
  const auto huge = check_queue(0, limits, 11);
  ASSERT_TRUE(huge);
  EXPECT_NE(huge->find("a sequence of 11 frames"), std::string::npos) << *huge;
  wire::FrameList frames = protocol::frames_to_wire({-5, 1000, 5});
  EXPECT_EQ(protocol::frame_count(frames), 202u);
  EXPECT_EQ(protocol::frame_count(wire::FrameList{}), 1u);
  wire::FrameList everything;
  everything.set_first(INT64_MIN);
  everything.set_last(INT64_MAX);
  everything.set_step(1);
  EXPECT_GT(protocol::frame_count(everything), 1u);  // never wraps to 0
  ASSERT_TRUE(check_queue(0, limits, protocol::frame_count(everything)));
}

}  // namespace
}  // namespace rayfarm::master
