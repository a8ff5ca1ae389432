// The scheduler without sockets: units go out lowest first (pass-major), jobs by priority and
// then by fair share (fewest leases now), one lease per request; a paused job gets none, only units
// released to the job; a lost worker's units go back to the queue ahead of fresh ones; a merged
// unit leaves the queue, whoever finished it. A blocked worker gets only other jobs' units; a
// straggler is leased a second time to an idle worker, and the first result ends both leases.
// A lease may cover a run of one tile's pending passes, sized by the worker's measured time per
// unit; fair sharing counts leases, not units.
#include <gtest/gtest.h>

#include "master/scheduler.h"

namespace rayfarm::master {
namespace {

/// A job whose every unit is needed.
void add_job(Scheduler& s, const std::string& job, uint64_t units) {
  s.add_job(job);
  s.release_all(job, units);
}

uint64_t lease_unit(Scheduler& s, const WorkerId& w) {
  const auto ref = s.lease(w);
  EXPECT_TRUE(ref.has_value());
  return ref ? ref->unit : ~uint64_t{0};
}

TEST(Scheduler, LeasesLowestFirstAndSharesBetweenJobs) {
  Scheduler s;
  add_job(s, "a", 3);
  add_job(s, "b", 2);
  // Equal priority: each lease goes to the job holding the fewest (ties to the older job).
  EXPECT_EQ(s.lease("w1"), (UnitRef{"a", 0}));
  EXPECT_EQ(s.lease("w2"), (UnitRef{"b", 0}));
  EXPECT_EQ(s.lease("w1"), (UnitRef{"a", 1}));
  EXPECT_EQ(s.lease("w3"), (UnitRef{"b", 1}));
  EXPECT_EQ(s.leased_units("w1"), (std::vector<UnitRef>{{"a", 0}, {"a", 1}}));
  EXPECT_EQ(s.counts("a").leased, 2u);
  EXPECT_EQ(s.counts("a").workers, 1u);
  EXPECT_EQ(s.counts("b").leased, 2u);
  EXPECT_EQ(s.counts("b").workers, 2u);
  EXPECT_TRUE(s.holds({"b", 0}, "w2"));
  EXPECT_FALSE(s.holds({"b", 0}, "w1"));
  EXPECT_EQ(s.lease("w2"), (UnitRef{"a", 2})) << "b has no unit left";
  EXPECT_FALSE(s.has_pending());
}

TEST(Scheduler, AJobSubmittedBehindALongOneGetsTheNextFreeWorker) {
  Scheduler s;
  add_job(s, "long", 1000);
  for (int w = 0; w < 8; ++w) lease_unit(s, "w" + std::to_string(w));
  add_job(s, "short", 3);
  // Each worker that frees up goes to the short job while it holds fewer leases than the long
  // one, ahead of the long job's 992 units waiting.
  for (const int w : {3, 5, 6}) {
    ASSERT_TRUE(s.complete({"long", uint64_t(w)}, "w" + std::to_string(w)));
    const auto ref = s.lease("w" + std::to_string(w));
    ASSERT_TRUE(ref);
    EXPECT_EQ(ref->job, "short");
  }
  EXPECT_EQ(s.counts("short").leased, 3u);
  ASSERT_TRUE(s.complete({"long", 7}, std::string("w7")));
  EXPECT_EQ(s.lease("w7"), (UnitRef{"long", 8})) << "the short job has nothing left";
}

TEST(Scheduler, ASequencesFramesGoInOrderAndShareTheFarmAsOneJob) {
  Scheduler s;
  // Frames added out of order (a restart lists folders by name): rank decides.
  for (const int frame : {3, 1, 2}) {
    s.add_job("seq." + std::to_string(frame), "seq", frame);
    s.release_all("seq." + std::to_string(frame), 2);
  }
  add_job(s, "other", 100);
  // One worker at a time: the sequence and the other job take turns, and the sequence's turns
  // take frame 1's units, then frame 2's, then frame 3's.
  std::string sequence_order;
  size_t other = 0;
  for (int i = 0; i < 12; ++i) {
    const auto ref = s.lease("w");
    ASSERT_TRUE(ref);
    if (ref->job == "other") {
      ++other;
    } else {
      sequence_order += ref->job.substr(4) + ",";
    }
    ASSERT_TRUE(s.complete(*ref, std::string("w")));
  }
  EXPECT_EQ(sequence_order, "1,1,2,2,3,3,");
  EXPECT_EQ(other, 6u);
  // Eight workers: the sequence holds four leases at most (its share, counted over its frames),
  // the other job four.
  Scheduler wide;
  for (int frame = 1; frame <= 4; ++frame) {
    wide.add_job("f" + std::to_string(frame), "seq", frame);
    wide.release_all("f" + std::to_string(frame), 3);
  }
  add_job(wide, "other", 100);
  std::string sequence_jobs;
  for (int w = 0; w < 8; ++w) {
    const auto ref = wide.lease("w" + std::to_string(w));
    ASSERT_TRUE(ref);
    if (ref->job != "other") sequence_jobs += ref->job + ",";
  }
  EXPECT_EQ(sequence_jobs, "f1,f1,f1,f2,") << "frame 1 has 3 units, then frame 2";
  // A paused frame is skipped; the next one is offered.
  Scheduler paused;
  for (int frame = 1; frame <= 2; ++frame) {
    paused.add_job("f" + std::to_string(frame), "seq", frame);
    paused.release_all("f" + std::to_string(frame), 1);
  }
  paused.set_paused("f1", true);
  EXPECT_EQ(paused.lease("w"), (UnitRef{"f2", 0}));
}

TEST(Scheduler, EqualJobsAlternateOnOneWorker) {
  // One worker taking one unit at a time: the jobs take turns (each holds none when it asks), so
  // neither waits for the other to finish.
  Scheduler s;
  add_job(s, "a", 4);
  add_job(s, "b", 4);
  add_job(s, "c", 4);
  std::string order;
  for (int i = 0; i < 12; ++i) {
    const auto ref = s.lease("w");
    ASSERT_TRUE(ref);
    order += ref->job;
    ASSERT_TRUE(s.complete(*ref, std::string("w")));
  }
  EXPECT_EQ(order, "abcabcabcabc");
  EXPECT_FALSE(s.lease("w"));
}

TEST(Scheduler, HigherPriorityFirstAndChangeableWhileRunning) {
  Scheduler s;
  add_job(s, "low", 3);
  add_job(s, "high", 2);
  s.set_priority("low", -5);
  s.set_priority("high", 10);
  EXPECT_EQ(s.lease("w1"), (UnitRef{"high", 0}));
  EXPECT_EQ(s.lease("w2"), (UnitRef{"high", 1})) << "priority beats the fair share";
  EXPECT_EQ(s.lease("w3"), (UnitRef{"low", 0})) << "high has nothing left";
  add_job(s, "mid", 3);
  s.set_priority("low", 20);  // raised while it runs
  EXPECT_EQ(s.lease("w4"), (UnitRef{"low", 1}));
  EXPECT_EQ(s.lease("w5"), (UnitRef{"low", 2}));
  EXPECT_EQ(s.lease("w6"), (UnitRef{"mid", 0}));
  s.set_priority("nobody", 3);  // unknown: ignored
}

TEST(Scheduler, APausedJobGetsNoLeasesUntilResumed) {
  Scheduler s;
  add_job(s, "a", 3);
  add_job(s, "b", 1);
  EXPECT_EQ(s.lease("w1"), (UnitRef{"a", 0}));
  s.set_paused("a", true);
  EXPECT_EQ(s.lease("w2"), (UnitRef{"b", 0}));
  EXPECT_FALSE(s.lease("w2")) << "a is paused";
  EXPECT_FALSE(s.has_pending()) << "a's units wait, but not for a worker";
  // A lease it held before the pause still completes.
  EXPECT_TRUE(s.holds({"a", 0}, "w1"));
  EXPECT_TRUE(s.complete({"a", 0}, std::string("w1")));
  // A lost worker's unit of a paused job waits in the queue too.
  s.set_paused("a", false);
  EXPECT_EQ(s.lease("w3"), (UnitRef{"a", 1}));
  s.set_paused("a", true);
  EXPECT_EQ(s.release_worker("w3"), (std::vector<UnitRef>{{"a", 1}}));
  EXPECT_FALSE(s.lease("w4"));
  s.set_paused("a", false);
  EXPECT_TRUE(s.has_pending());
  EXPECT_EQ(s.lease("w4"), (UnitRef{"a", 1}));
  EXPECT_EQ(s.lease("w4"), (UnitRef{"a", 2}));
}

TEST(Scheduler, NothingPendingMeansNoLease) {
  Scheduler s;
  EXPECT_FALSE(s.lease("w"));
  s.add_job("a");
  EXPECT_FALSE(s.has_pending()) << "nothing released yet";
  s.release_all("a", 1);
  EXPECT_TRUE(s.lease("w"));
  EXPECT_FALSE(s.has_pending());
  EXPECT_FALSE(s.lease("w"));
}

TEST(Scheduler, LostWorkerUnitsAreRequeuedAheadOfFreshOnes) {
  Scheduler s;
  add_job(s, "a", 10);
  lease_unit(s, "w1");  // 0
  lease_unit(s, "w2");  // 1
  lease_unit(s, "w1");  // 2
  const auto released = s.release_worker("w1");
  EXPECT_EQ(released, (std::vector<UnitRef>{{"a", 0}, {"a", 2}}));
  EXPECT_TRUE(s.leased_units("w1").empty());
  EXPECT_EQ(s.counts("a").leased, 1u);
  EXPECT_EQ(lease_unit(s, "w3"), 0u);
  EXPECT_EQ(lease_unit(s, "w3"), 2u);
  EXPECT_EQ(lease_unit(s, "w3"), 3u);
  EXPECT_TRUE(s.release_worker("nobody").empty());
}

TEST(Scheduler, AUnitIsCompletedOnceWhoeverFinishesIt) {
  Scheduler s;
  add_job(s, "a", 3);
  lease_unit(s, "w1");  // 0
  s.release_worker("w1");
  lease_unit(s, "w2");  // 0 again
  // The lost worker's late result arrives first: it counts, and w2's lease ends.
  EXPECT_TRUE(s.complete({"a", 0}));
  EXPECT_TRUE(s.leased_units("w2").empty());
  EXPECT_FALSE(s.complete({"a", 0}));
  EXPECT_FALSE(s.complete({"a", 7}));
  EXPECT_FALSE(s.complete({"zz", 0}));
  EXPECT_EQ(s.counts("a").leased, 0u);
  EXPECT_EQ(lease_unit(s, "w2"), 1u);
  EXPECT_EQ(lease_unit(s, "w2"), 2u);
  EXPECT_FALSE(s.lease("w2")) << "unit 0 is not handed out again";
}

TEST(Scheduler, ARequeuedUnitFinishedLateLeavesTheQueue) {
  Scheduler s;
  add_job(s, "a", 2);
  lease_unit(s, "w1");  // 0
  s.release_worker("w1");
  EXPECT_TRUE(s.complete({"a", 0}));  // late result while 0 waits in the queue
  EXPECT_EQ(lease_unit(s, "w2"), 1u);
  EXPECT_FALSE(s.lease("w2"));
}

TEST(Scheduler, OnlyReleasedUnitsAreHandedOut) {
  // A job resumed with units 0 and 1 merged: only unit 2 is released to it.
  Scheduler s;
  s.add_job("a");
  s.release("a", {2});
  EXPECT_EQ(lease_unit(s, "w"), 2u);
  EXPECT_FALSE(s.lease("w"));
}

TEST(Scheduler, RequeueOfAFailedUnit) {
  Scheduler s;
  add_job(s, "a", 2);
  lease_unit(s, "w1");  // 0
  EXPECT_TRUE(s.requeue({"a", 0}));
  EXPECT_FALSE(s.requeue({"a", 0}));
  EXPECT_FALSE(s.holds({"a", 0}, "w1"));
  EXPECT_EQ(s.counts("a").leased, 0u);
  EXPECT_EQ(lease_unit(s, "w2"), 0u);
  EXPECT_TRUE(s.holds({"a", 0}, "w2"));
}

TEST(Scheduler, RemovingAJobDropsItsLeases) {
  Scheduler s;
  add_job(s, "a", 2);
  add_job(s, "b", 1);
  lease_unit(s, "w");
  s.remove_job("a");
  EXPECT_TRUE(s.leased_units("w").empty());
  EXPECT_FALSE(s.complete({"a", 0}));
  const auto next = s.lease("w");
  ASSERT_TRUE(next);
  EXPECT_EQ(next->job, "b");
  EXPECT_TRUE(s.release_worker("w") == (std::vector<UnitRef>{{"b", 0}}));
}

TEST(Scheduler, UnitsReleasedAsTheRenderGoesAreHandedOutLowestFirst) {
  Scheduler s;
  s.add_job("a");
  EXPECT_FALSE(s.has_pending());
  EXPECT_FALSE(s.lease("w1"));
  s.release("a", {4, 2});
  EXPECT_EQ(lease_unit(s, "w1"), 2u);
  s.release("a", {3});
  EXPECT_EQ(lease_unit(s, "w1"), 3u);
  EXPECT_EQ(lease_unit(s, "w2"), 4u);
  EXPECT_FALSE(s.lease("w1"));
  // A lost worker's unit comes back like any other.
  EXPECT_EQ(s.release_worker("w2").size(), 1u);
  EXPECT_EQ(lease_unit(s, "w1"), 4u);
  EXPECT_TRUE(s.complete({"a", 4}));
  EXPECT_FALSE(s.has_pending());
}

TEST(Scheduler, ABlockedWorkerGetsOnlyOtherJobsUnits) {
  Scheduler s;
  add_job(s, "a", 2);
  add_job(s, "b", 1);
  s.block("a", "bad");
  EXPECT_TRUE(s.is_blocked("a", "bad"));
  EXPECT_FALSE(s.is_blocked("b", "bad"));
  const auto got = s.lease("bad");
  ASSERT_TRUE(got);
  EXPECT_EQ(*got, (UnitRef{"b", 0}));
  EXPECT_FALSE(s.lease("bad")) << "only job a has units left, and bad is blocked from it";
  EXPECT_TRUE(s.has_pending());
  EXPECT_EQ(lease_unit(s, "good"), 0u);
}

using namespace std::chrono_literals;

/// Three units leased by w1 at t0 and done at t0 + 1 s: their job's median becomes 1 s.
void three_units_of_one_second(Scheduler& s, Scheduler::Clock::time_point t0) {
  for (int i = 0; i < 3; ++i) {
    const auto u = s.lease("w1", t0);
    ASSERT_TRUE(u);
    EXPECT_TRUE(s.complete(*u, WorkerId("w1"), t0 + 1s));
  }
}

TEST(Scheduler, AStragglerIsLeasedTwiceAndTheFirstResultEndsBothLeases) {
  Scheduler s;
  add_job(s, "a", 6);
  const StragglerPolicy policy{4.0, 5000ms, 3};
  const auto t0 = Scheduler::Clock::now();
  three_units_of_one_second(s, t0);
  ASSERT_TRUE(s.lease("slow", t0 + 1s));  // unit 3
  ASSERT_TRUE(s.lease("w1", t0 + 1s));    // unit 4
  ASSERT_TRUE(s.lease("w2", t0 + 1s));    // unit 5
  EXPECT_FALSE(s.lease("idle", t0 + 1s));
  // 4 s is 4x the median but under the 5 s floor: not yet.
  EXPECT_FALSE(s.has_straggler(policy, t0 + 5s));
  EXPECT_FALSE(s.lease_straggler("idle", policy, t0 + 5s));
  // Past both: the oldest lease is the straggler; its own holder never gets it twice.
  EXPECT_TRUE(s.has_straggler(policy, t0 + 7s));
  EXPECT_TRUE(s.complete({"a", 4}, WorkerId("w1"), t0 + 2s));
  EXPECT_TRUE(s.complete({"a", 5}, WorkerId("w2"), t0 + 2s));
  EXPECT_FALSE(s.lease_straggler("slow", policy, t0 + 7s));
  const auto again = s.lease_straggler("idle", policy, t0 + 7s);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->unit, (UnitRef{"a", 3}));
  EXPECT_EQ(again->first, "slow");
  EXPECT_DOUBLE_EQ(again->leased_seconds, 6.0);
  EXPECT_TRUE(s.holds({"a", 3}, "slow"));
  EXPECT_TRUE(s.holds({"a", 3}, "idle"));
  EXPECT_DOUBLE_EQ(again->median_seconds, 1.0);
  EXPECT_EQ(s.counts("a").leased, 1u);
  EXPECT_EQ(s.counts("a").workers, 2u);
  // Held twice: no third copy.
  EXPECT_FALSE(s.has_straggler(policy, t0 + 60s));
  EXPECT_FALSE(s.lease_straggler("third", policy, t0 + 60s));
  // One holder lost: the other keeps it, nothing is requeued.
  EXPECT_TRUE(s.release_worker("slow").empty());
  EXPECT_FALSE(s.holds({"a", 3}, "slow"));
  EXPECT_TRUE(s.holds({"a", 3}, "idle"));
  EXPECT_FALSE(s.has_pending());
  // The result ends the lease; a late one from anybody else finds nothing to complete.
  EXPECT_TRUE(s.complete({"a", 3}, WorkerId("idle"), t0 + 8s));
  EXPECT_TRUE(s.leased_units("idle").empty());
  EXPECT_FALSE(s.complete({"a", 3}, WorkerId("slow"), t0 + 9s));
  EXPECT_EQ(s.counts("a").leased, 0u);
  EXPECT_FALSE(s.has_pending());
}

TEST(Scheduler, APausedJobsStragglerIsNotLeasedAgain) {
  Scheduler s;
  add_job(s, "a", 4);
  const StragglerPolicy policy{4.0, 5000ms, 3};
  const auto t0 = Scheduler::Clock::now();
  three_units_of_one_second(s, t0);
  ASSERT_TRUE(s.lease("slow", t0 + 1s));  // unit 3
  ASSERT_TRUE(s.has_straggler(policy, t0 + 60s));
  s.set_paused("a", true);
  EXPECT_FALSE(s.has_straggler(policy, t0 + 60s));
  EXPECT_FALSE(s.lease_straggler("idle", policy, t0 + 60s));
  s.set_paused("a", false);
  EXPECT_TRUE(s.lease_straggler("idle", policy, t0 + 60s));
}

TEST(Scheduler, BothLeasesOfAStragglerEndWhenEitherFinishesOrFails) {
  Scheduler s;
  add_job(s, "a", 4);
  const StragglerPolicy policy{2.0, 0ms, 1};
  const auto t0 = Scheduler::Clock::now();
  const auto first = s.lease("w1", t0);
  ASSERT_TRUE(first);
  EXPECT_TRUE(s.complete(*first, WorkerId("w1"), t0 + 1s));
  ASSERT_TRUE(s.lease("slow", t0));  // unit 1
  ASSERT_TRUE(s.lease("w1", t0));    // unit 2
  ASSERT_TRUE(s.lease("w1", t0));    // unit 3
  const auto again = s.lease_straggler("w2", policy, t0 + 3s);
  ASSERT_TRUE(again);
  // The second holder fails it: the first still holds it, so it is not requeued.
  EXPECT_TRUE(s.requeue(again->unit, WorkerId("w2")));
  EXPECT_FALSE(s.requeue(again->unit, WorkerId("w2")));
  EXPECT_TRUE(s.holds(again->unit, "slow"));
  EXPECT_FALSE(s.holds(again->unit, "w2"));
  EXPECT_FALSE(s.has_pending());
  // The first holder's result arrives: both leases are gone.
  ASSERT_TRUE(s.lease_straggler("w3", policy, t0 + 4s));
  EXPECT_TRUE(s.complete(again->unit, WorkerId("slow"), t0 + 4s));
  EXPECT_TRUE(s.leased_units("slow").empty());
  EXPECT_TRUE(s.leased_units("w3").empty());
  // A policy factor of 0 never leases twice.
  EXPECT_FALSE(s.lease_straggler("w3", StragglerPolicy{0.0, 0ms, 1}, t0 + 100s));
}

/// A job of `tiles` tiles x `passes` passes, every unit needed, runs along its tiles' passes.
void add_grid_job(Scheduler& s, const std::string& job, uint64_t tiles, uint64_t passes) {
  add_job(s, job, tiles * passes);
  s.set_run_stride(job, tiles);
}

std::vector<uint64_t> run_of(Scheduler& s, const WorkerId& w, const RunPolicy& runs,
                             Scheduler::Clock::time_point now) {
  const auto lease = s.lease_run(w, runs, now);
  EXPECT_TRUE(lease.has_value());
  return lease ? lease->units : std::vector<uint64_t>{};
}

TEST(Scheduler, ARunCoversOneTilesPendingPassesSizedByTheWorkersTimePerUnit) {
  Scheduler s;
  add_grid_job(s, "a", 3, 4);  // units: pass * 3 + tile
  const RunPolicy runs{4s, 8};
  const auto t0 = Scheduler::Clock::now();
  // Not measured yet: one unit.
  EXPECT_EQ(run_of(s, "w1", runs, t0), (std::vector<uint64_t>{0}));
  EXPECT_FALSE(s.unit_seconds("a", "w1"));
  EXPECT_TRUE(s.complete({"a", 0}, WorkerId("w1"), t0 + 1s));
  EXPECT_EQ(s.unit_seconds("a", "w1"), 1.0);
  // 1 s a unit, 4 s wanted: tile 1's four passes.
  EXPECT_EQ(run_of(s, "w1", runs, t0 + 1s), (std::vector<uint64_t>{1, 4, 7, 10}));
  EXPECT_EQ(s.lease_of({"a", 7}, "w1"), (std::vector<uint64_t>{1, 4, 7, 10}));
  EXPECT_TRUE(s.lease_of({"a", 7}, "w2").empty());
  EXPECT_EQ(s.counts("a").leased, 4u);
  EXPECT_EQ(run_of(s, "w2", runs, t0 + 1s), (std::vector<uint64_t>{2}));
  // The units taken ahead are skipped: tile 0's passes 1 to 3 (no unit 12 exists).
  EXPECT_EQ(run_of(s, "w1", runs, t0 + 1s), (std::vector<uint64_t>{3, 6, 9}));
  // w2 took 2 s a unit: two units of 4 s wanted.
  EXPECT_TRUE(s.complete({"a", 2}, WorkerId("w2"), t0 + 3s));
  EXPECT_EQ(run_of(s, "w2", runs, t0 + 3s), (std::vector<uint64_t>{5, 8}));
  EXPECT_EQ(run_of(s, "w2", runs, t0 + 3s), (std::vector<uint64_t>{11}));
  EXPECT_FALSE(s.has_pending());
  EXPECT_FALSE(s.lease_run("w3", runs, t0 + 3s));
  // A run's time counts per unit: 4 units in 2 s.
  for (uint64_t u : {1, 4, 7, 10}) EXPECT_TRUE(s.complete({"a", u}, WorkerId("w1"), t0 + 3s));
  EXPECT_EQ(s.unit_seconds("a", "w1"), 0.5);
  // A lost worker's run comes back unit by unit, and the next run takes them again in order.
  EXPECT_EQ(s.release_worker("w1"), (std::vector<UnitRef>{{"a", 3}, {"a", 6}, {"a", 9}}));
  EXPECT_FALSE(s.unit_seconds("a", "w1")) << "a lost worker's times are forgotten";
  EXPECT_EQ(run_of(s, "w2", runs, t0 + 4s), (std::vector<uint64_t>{3, 6}));
  EXPECT_EQ(run_of(s, "w2", runs, t0 + 4s), (std::vector<uint64_t>{9}));
}

TEST(Scheduler, ARunTakesOnlyReleasedUnitsAndStopsAtTheFirstMissing) {
  Scheduler s;
  s.add_job("a");
  s.set_run_stride("a", 2);
  const RunPolicy runs{100s, 32};
  const auto t0 = Scheduler::Clock::now();
  s.release("a", {0, 1});
  EXPECT_EQ(run_of(s, "w", runs, t0), (std::vector<uint64_t>{0}));
  EXPECT_TRUE(s.complete({"a", 0}, WorkerId("w"), t0 + 1s));
  s.release("a", {2, 3, 5, 7});  // tile 0: passes 1 (2); tile 1: passes 1 to 3 (3, 5, 7)
  EXPECT_EQ(run_of(s, "w", runs, t0 + 1s), (std::vector<uint64_t>{1, 3, 5, 7}));
  EXPECT_EQ(run_of(s, "w", runs, t0 + 1s), (std::vector<uint64_t>{2}));
  s.release("a", {4, 8});  // pass 2 of tile 0 and pass 4 of tile 0, not pass 3 (6)
  EXPECT_EQ(run_of(s, "w", runs, t0 + 1s), (std::vector<uint64_t>{4}));
  EXPECT_EQ(run_of(s, "w", runs, t0 + 1s), (std::vector<uint64_t>{8}));
  // A job without a stride, or a policy without a target, leases one unit at a time.
  s.add_job("b");
  s.release_all("b", 4);
  s.set_priority("b", 1);
  ASSERT_TRUE(s.lease_run("w", runs, t0));
  EXPECT_TRUE(s.complete({"b", 0}, WorkerId("w"), t0 + 1s));
  EXPECT_EQ(run_of(s, "w", runs, t0 + 1s), (std::vector<uint64_t>{1}));
  s.set_run_stride("b", 1);
  EXPECT_EQ(run_of(s, "w", RunPolicy{}, t0 + 1s), (std::vector<uint64_t>{2}));
  // A time per unit of zero (faster than the clock) gives the longest run allowed.
  EXPECT_TRUE(s.complete({"b", 2}, WorkerId("w"), t0 + 1s));
  EXPECT_EQ(run_of(s, "w", RunPolicy{4s, 2}, t0 + 1s), (std::vector<uint64_t>{3}));
}

TEST(Scheduler, FairSharingCountsLeasesNotTheUnitsOfARun) {
  Scheduler s;
  add_grid_job(s, "a", 2, 8);
  add_grid_job(s, "b", 2, 8);
  const RunPolicy runs{8s, 8};
  const auto t0 = Scheduler::Clock::now();
  EXPECT_EQ(s.lease_run("w1", runs, t0)->job, "a");
  EXPECT_TRUE(s.complete({"a", 0}, WorkerId("w1"), t0 + 1s));
  EXPECT_EQ(s.lease_run("w2", runs, t0 + 1s)->job, "b");
  const auto big = s.lease_run("w1", runs, t0 + 1s);  // a: one lease of tile 1's passes
  ASSERT_TRUE(big);
  EXPECT_EQ(big->job, "a");
  EXPECT_EQ(big->units.size(), 8u);
  EXPECT_EQ(s.lease_run("w3", runs, t0 + 1s)->job, "b");  // b: two leases, a: one
  EXPECT_EQ(s.lease_run("w4", runs, t0 + 1s)->job, "a") << "a holds 8 units but one lease";
}

TEST(Scheduler, AStragglingRunIsLeasedAgainWhole) {
  Scheduler s;
  add_grid_job(s, "a", 2, 4);
  const RunPolicy runs{4s, 8};
  const StragglerPolicy policy{4.0, 0ms, 1};
  const auto t0 = Scheduler::Clock::now();
  EXPECT_EQ(run_of(s, "slow", runs, t0), (std::vector<uint64_t>{0}));
  EXPECT_TRUE(s.complete({"a", 0}, WorkerId("slow"), t0 + 1s));  // 1 s a unit: the median
  EXPECT_EQ(run_of(s, "slow", runs, t0 + 1s), (std::vector<uint64_t>{1, 3, 5, 7}));
  // 4 units in 12 s is 3 s a unit: under 4x the median.
  EXPECT_FALSE(s.has_straggler(policy, t0 + 13s));
  EXPECT_TRUE(s.has_straggler(policy, t0 + 18s));
  const auto again = s.lease_straggler("idle", policy, t0 + 18s);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->units, (std::vector<uint64_t>{1, 3, 5, 7}));
  EXPECT_EQ(again->unit, (UnitRef{"a", 1}));
  EXPECT_DOUBLE_EQ(again->leased_seconds, 17.0);
  EXPECT_EQ(s.lease_of({"a", 5}, "idle"), (std::vector<uint64_t>{1, 3, 5, 7}));
  // Either result ends both leases of every unit.
  for (uint64_t u : {1, 3, 5, 7}) EXPECT_TRUE(s.complete({"a", u}, WorkerId("idle"), t0 + 19s));
  EXPECT_TRUE(s.leased_units("slow").empty());
  EXPECT_TRUE(s.leased_units("idle").empty());
  EXPECT_EQ(s.counts("a").leased, 0u);
}

}  // namespace
}  // namespace rayfarm::master
