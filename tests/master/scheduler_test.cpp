// The scheduler without sockets: units go out lowest first (pass-major), jobs in the order they
// came, one lease per request; a lost worker's units go back to the queue ahead of fresh ones; a
// unit is done once, whoever finishes it.
#include <gtest/gtest.h>

#include "master/scheduler.h"
#include "master/unit_grid.h"

namespace rayfarm::master {
namespace {

uint64_t lease_unit(Scheduler& s, const WorkerId& w) {
  const auto ref = s.lease(w);
  EXPECT_TRUE(ref.has_value());
  return ref ? ref->unit : ~uint64_t{0};
}

TEST(UnitGrid, NumbersUnitsPassMajor) {
  const UnitGrid grid({100, 50}, 64, 10, 4);  // 2 x 1 tiles, passes [0,4) [4,8) [8,10)
  ASSERT_EQ(grid.tile_count(), 2u);
  ASSERT_EQ(grid.pass_count(), 3u);
  ASSERT_EQ(grid.size(), 6u);
  EXPECT_EQ(grid.unit(0).rect, (TileRect{0, 0, 64, 50}));
  EXPECT_EQ(grid.unit(1).rect, (TileRect{64, 0, 100, 50}));
  EXPECT_EQ(grid.unit(1).pass, 0u);
  EXPECT_EQ(grid.unit(2).pass, 1u);
  EXPECT_EQ(grid.unit(2).samples, (SampleRange{4, 8}));
  EXPECT_EQ(grid.unit(5).samples, (SampleRange{8, 10}));
  uint64_t total = 0;
  for (uint64_t u = 0; u < grid.size(); ++u) total += grid.samples_in(u);
  EXPECT_EQ(total, grid.samples_total());
  EXPECT_EQ(total, 100u * 50u * 10u);
}

TEST(Scheduler, LeasesLowestFirstAndJobsInOrder) {
  Scheduler s;
  s.add_job("a", 3);
  s.add_job("b", 2);
  EXPECT_EQ(lease_unit(s, "w1"), 0u);
  EXPECT_EQ(lease_unit(s, "w2"), 1u);
  EXPECT_EQ(lease_unit(s, "w1"), 2u);
  const auto next = s.lease("w1");
  ASSERT_TRUE(next);
  EXPECT_EQ(*next, (UnitRef{"b", 0}));
  EXPECT_EQ(s.leases_of("w1"), 3u);
  EXPECT_EQ(s.counts("a").leased, 3u);
  EXPECT_EQ(s.counts("a").workers, 2u);
  EXPECT_EQ(s.counts("b").pending, 1u);
}

TEST(Scheduler, NothingPendingMeansNoLease) {
  Scheduler s;
  EXPECT_FALSE(s.lease("w"));
  s.add_job("a", 1);
  EXPECT_TRUE(s.lease("w"));
  EXPECT_FALSE(s.has_pending());
  EXPECT_FALSE(s.lease("w"));
}

TEST(Scheduler, LostWorkerUnitsAreRequeuedAheadOfFreshOnes) {
  Scheduler s;
  s.add_job("a", 10);
  lease_unit(s, "w1");  // 0
  lease_unit(s, "w2");  // 1
  lease_unit(s, "w1");  // 2
  const auto released = s.release_worker("w1");
  EXPECT_EQ(released, (std::vector<UnitRef>{{"a", 0}, {"a", 2}}));
  EXPECT_EQ(s.leases_of("w1"), 0u);
  EXPECT_EQ(s.counts("a").pending, 9u);
  EXPECT_EQ(lease_unit(s, "w3"), 0u);
  EXPECT_EQ(lease_unit(s, "w3"), 2u);
  EXPECT_EQ(lease_unit(s, "w3"), 3u);
  EXPECT_TRUE(s.release_worker("nobody").empty());
}

TEST(Scheduler, AUnitIsDoneOnceWhoeverFinishesIt) {
  Scheduler s;
  s.add_job("a", 3);
  lease_unit(s, "w1");  // 0
  s.release_worker("w1");
  lease_unit(s, "w2");  // 0 again
  // The lost worker's late result arrives first: it counts, and w2's lease ends.
  EXPECT_TRUE(s.complete({"a", 0}));
  EXPECT_EQ(s.leases_of("w2"), 0u);
  EXPECT_FALSE(s.complete({"a", 0}));
  EXPECT_TRUE(s.is_done({"a", 0}));
  EXPECT_FALSE(s.complete({"a", 7}));
  EXPECT_FALSE(s.complete({"zz", 0}));
  const auto c = s.counts("a");
  EXPECT_EQ(c.done, 1u);
  EXPECT_EQ(c.pending, 2u);
}

TEST(Scheduler, ARequeuedUnitFinishedLateLeavesTheQueue) {
  Scheduler s;
  s.add_job("a", 2);
  lease_unit(s, "w1");  // 0
  s.release_worker("w1");
  EXPECT_TRUE(s.complete({"a", 0}));  // late result while 0 waits in the queue
  EXPECT_EQ(lease_unit(s, "w2"), 1u);
  EXPECT_FALSE(s.lease("w2"));
}

TEST(Scheduler, UnitsDoneBeforeBeingHandedOutAreSkipped) {
  Scheduler s;
  s.add_job("a", 3);
  EXPECT_TRUE(s.complete({"a", 0}));
  EXPECT_TRUE(s.complete({"a", 1}));
  EXPECT_EQ(lease_unit(s, "w"), 2u);
  EXPECT_FALSE(s.lease("w"));
}

TEST(Scheduler, RequeueOfAFailedUnit) {
  Scheduler s;
  s.add_job("a", 2);
  lease_unit(s, "w1");  // 0
  EXPECT_TRUE(s.requeue({"a", 0}));
  EXPECT_FALSE(s.requeue({"a", 0}));
  EXPECT_FALSE(s.holder({"a", 0}));
  EXPECT_EQ(lease_unit(s, "w2"), 0u);
  EXPECT_EQ(s.holder({"a", 0}), std::optional<WorkerId>("w2"));
}

TEST(Scheduler, RemovingAJobDropsItsLeases) {
  Scheduler s;
  s.add_job("a", 2);
  s.add_job("b", 1);
  lease_unit(s, "w");
  s.remove_job("a");
  EXPECT_FALSE(s.has_job("a"));
  EXPECT_EQ(s.leases_of("w"), 0u);
  const auto next = s.lease("w");
  ASSERT_TRUE(next);
  EXPECT_EQ(next->job, "b");
  EXPECT_TRUE(s.release_worker("w") == (std::vector<UnitRef>{{"b", 0}}));
}

}  // namespace
}  // namespace rayfarm::master
