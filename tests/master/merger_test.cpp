// The merger without sockets: each unit merges once (a duplicate is dropped, the film untouched),
// a result that does not match its unit is rejected before Film::add, and any order of arrival
// gives the same bits as merging in unit order.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "master/merger.h"

namespace rayfarm::master {
namespace {

/// A deterministic fake result for unit `id`: sums from a generator seeded by the unit.
TileResult fake_result(const UnitGrid& grid, uint64_t id) {
  const UnitGrid::Unit u = grid.unit(id);
  TileResult r(u.rect, u.samples);
  std::mt19937_64 rng(id * 7919 + 1);
  const double n = u.samples.count();
  for (size_t i = 0; i < r.sum.size(); ++i) {
    // Sums that samples of this mean and spread could have (Merger refuses impossible ones).
    const double mean = static_cast<double>(rng() % 100000) / 4096.0;
    const double spread = static_cast<double>(rng() % 100000) / 1024.0;
    r.sum[i] = to_fixed(mean * n);
    r.sum_sq[i] = to_fixed((mean * mean + spread) * n);
  }
  r.rays = u.rect.pixel_count();
  return r;
}

const UnitGrid kGrid({70, 40}, 32, 24, 8);  // 3 x 2 tiles x 3 passes = 18 units

TEST(Merger, MergesEachUnitOnceAndDropsDuplicates) {
  Merger m(kGrid);
  const TileResult r = fake_result(kGrid, 4);
  EXPECT_EQ(m.add(4, r), MergeOutcome::kMerged);
  const std::vector<Fixed> before = m.film().sum();
  EXPECT_EQ(m.add(4, r), MergeOutcome::kDuplicate);
  EXPECT_TRUE(m.film().sum() == before);
  EXPECT_EQ(m.merged_count(), 1u);
  EXPECT_TRUE(m.merged(4));
  EXPECT_FALSE(m.merged(5));
}

TEST(Merger, RejectsResultsThatDoNotMatchTheirUnit) {
  Merger m(kGrid);
  std::string why;
  // Another unit's tile.
  EXPECT_EQ(m.add(0, fake_result(kGrid, 1), &why), MergeOutcome::kRejected);
  EXPECT_NE(why.find("unit 0"), std::string::npos) << why;
  // The right tile, another pass.
  EXPECT_EQ(m.add(0, fake_result(kGrid, 6), &why), MergeOutcome::kRejected);
  // The right tile and samples, sums of the wrong size.
  TileResult short_sums = fake_result(kGrid, 0);
  short_sums.sum.pop_back();
  EXPECT_EQ(m.add(0, short_sums, &why), MergeOutcome::kRejected);
  EXPECT_NE(why.find("malformed"), std::string::npos) << why;
  // A unit that does not exist.
  EXPECT_EQ(m.add(18, fake_result(kGrid, 0), &why), MergeOutcome::kRejected);
  EXPECT_EQ(m.merged_count(), 0u);
  EXPECT_EQ(m.film().min_spp(), 0u);
  // The real result still merges afterwards.
  EXPECT_EQ(m.add(0, fake_result(kGrid, 0)), MergeOutcome::kMerged);
}

TEST(Merger, AnyOrderOfArrivalGivesTheSameBits) {
  Merger in_order(kGrid);
  for (uint64_t u = 0; u < kGrid.size(); ++u)
    ASSERT_EQ(in_order.add(u, fake_result(kGrid, u)), MergeOutcome::kMerged);
  ASSERT_TRUE(in_order.complete());
  const std::vector<float> reference = in_order.film().mean_rgb();

  std::vector<uint64_t> order(kGrid.size());
  for (uint64_t u = 0; u < order.size(); ++u) order[u] = u;
  std::mt19937 rng(3);
  for (int trial = 0; trial < 5; ++trial) {
    std::shuffle(order.begin(), order.end(), rng);
    Merger shuffled(kGrid);
    for (uint64_t u : order) {
      shuffled.add(u, fake_result(kGrid, u));
      shuffled.add(u, fake_result(kGrid, u));  // every result twice: duplicates change nothing
    }
    ASSERT_TRUE(shuffled.complete());
    EXPECT_TRUE(shuffled.film().sum() == in_order.film().sum());
    EXPECT_TRUE(shuffled.film().sum_sq() == in_order.film().sum_sq());
    EXPECT_TRUE(shuffled.film().mean_rgb() == reference);
    EXPECT_EQ(shuffled.film().min_spp(), 24u);
  }
}

/// The result of a run: the sums of its units' results, over the run's samples (what a worker
/// rendering the run's samples at once returns: the samples are the same, summed exactly).
TileResult run_result(const UnitGrid& grid, uint64_t first, uint32_t units) {
  TileResult r(grid.tile(grid.tile_of(first)), grid.run_samples(first, units));
  for (uint32_t k = 0; k < units; ++k) {
    const TileResult part = fake_result(grid, first + k * grid.tile_count());
    for (size_t i = 0; i < r.sum.size(); ++i) {
      r.sum[i] += part.sum[i];
      r.sum_sq[i] += part.sum_sq[i];
    }
    r.rays += part.rays;
  }
  return r;
}

TEST(Merger, ARunMergesAsItsUnitsWithTheSameBits) {
  Merger by_unit(kGrid), by_run(kGrid);
  for (uint64_t u = 0; u < kGrid.size(); ++u) by_unit.add(u, fake_result(kGrid, u));
  // Tile 0 as one run of its 3 passes; tile 1 as pass 0, then a run of passes 1 and 2; the
  // other tiles unit by unit.
  std::string why;
  EXPECT_EQ(by_run.add(0, run_result(kGrid, 0, 3), &why, 3), MergeOutcome::kMerged) << why;
  EXPECT_EQ(by_run.add(1, fake_result(kGrid, 1)), MergeOutcome::kMerged);
  EXPECT_EQ(by_run.add(7, run_result(kGrid, 7, 2), &why, 2), MergeOutcome::kMerged) << why;
  EXPECT_EQ(by_run.merged_units().in_tile(0), 3u);
  EXPECT_EQ(by_run.merged_units().in_tile(1), 3u);
  EXPECT_EQ(by_run.samples_merged(), 2u * 32u * 32u * 24u);
  for (uint64_t u = 0; u < kGrid.size(); ++u) {
    if (!by_run.merged(u)) by_run.add(u, fake_result(kGrid, u));
  }
  ASSERT_TRUE(by_run.complete());
  EXPECT_TRUE(by_run.film().sum() == by_unit.film().sum());
  EXPECT_TRUE(by_run.film().sum_sq() == by_unit.film().sum_sq());
  EXPECT_EQ(by_run.film().min_spp(), 24u);
}

TEST(Merger, ARunOverlappingMergedUnitsIsADuplicateAndAWrongRunIsRejected) {
  Merger m(kGrid);
  ASSERT_EQ(m.add(12, fake_result(kGrid, 12)), MergeOutcome::kMerged);  // tile 0, pass 2
  const std::vector<Fixed> before = m.film().sum();
  // The run of tile 0's three passes holds unit 12: its sums cannot be split, nothing is added.
  EXPECT_EQ(m.add(0, run_result(kGrid, 0, 3), nullptr, 3), MergeOutcome::kDuplicate);
  EXPECT_TRUE(m.film().sum() == before);
  EXPECT_FALSE(m.merged(0));
  EXPECT_FALSE(m.merged(6));
  std::string why;
  // A run claimed longer than its samples, one past the last pass, one of no units.
  EXPECT_EQ(m.add(1, run_result(kGrid, 1, 2), &why, 3), MergeOutcome::kRejected);
  EXPECT_NE(why.find("the run of 3 units from 1"), std::string::npos) << why;
  EXPECT_EQ(m.add(7, run_result(kGrid, 7, 2), &why, 3), MergeOutcome::kRejected);
  EXPECT_NE(why.find("no run of 3 units"), std::string::npos) << why;
  EXPECT_FALSE(m.covers(1, kGrid.tile(1), kGrid.run_samples(1, 2), &why, 0));
  EXPECT_EQ(m.merged_count(), 1u);
  EXPECT_EQ(m.add(1, run_result(kGrid, 1, 2), &why, 2), MergeOutcome::kMerged) << why;
}

TEST(Merger, OwnsWhichUnitsAreMergedTileByTile) {
  Merger m(kGrid);
  for (uint64_t u = 6; u < 12; ++u) m.add(u, fake_result(kGrid, u));  // all of pass 1
  for (uint64_t u = 0; u < 5; ++u) m.add(u, fake_result(kGrid, u));
  const MergedUnits& merged = m.merged_units();
  EXPECT_EQ(merged.count(), 11u);
  EXPECT_EQ(merged.in_tile(0), 2u);
  EXPECT_EQ(merged.in_tile(5), 1u) << "tile 5 has pass 1, not pass 0";
  EXPECT_FALSE(merged.contains(5));
  m.add(5, fake_result(kGrid, 5));
  EXPECT_EQ(merged.in_tile(5), 2u);
  EXPECT_EQ(m.samples_merged(), 70u * 40u * 16u);
  EXPECT_FALSE(m.complete());
}

TEST(Merger, FewestSamplesOfAnyPixelComeFromTheTilesAndSurviveARestore) {
  Merger m(kGrid);
  EXPECT_EQ(m.min_spp(), 0u);
  std::mt19937 rng(9);
  for (int step = 0; step < 12; ++step) {
    const uint64_t unit = rng() % kGrid.size();
    m.add(unit, fake_result(kGrid, unit));
    EXPECT_EQ(m.min_spp(), m.film().min_spp()) << "after unit " << unit;
  }
  for (uint64_t u = 0; u < kGrid.size(); ++u) m.add(u, fake_result(kGrid, u));
  EXPECT_EQ(m.min_spp(), 24u);
  Merger partial(kGrid);
  for (uint64_t u : {0, 1, 2, 3, 4, 5, 7}) partial.add(u, fake_result(kGrid, u));
  Merger restored(kGrid);
  const Film& f = partial.film();
  restored.restore(partial.merged_units().to_bytes(), f.sum(), f.sum_sq(), f.nonfinite(), f.rays());
  EXPECT_EQ(restored.min_spp(), 8u);
  EXPECT_EQ(restored.min_spp(), f.min_spp());
}

}  // namespace
}  // namespace rayfarm::master
