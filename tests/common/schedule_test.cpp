// The scheduling of a render: the grid of units (every tile for every pass, numbered
// pass-major), the pass planner that stops tiles under a target error, and the stopping rules.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "common/image/error_estimate.h"
#include "common/schedule/pass_planner.h"
#include "common/schedule/unit_grid.h"

namespace rayfarm {
namespace {

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
  for (uint64_t u = 0; u < grid.size(); ++u) {
    EXPECT_EQ(grid.id(grid.pass_of(u), grid.tile_of(u)), u);
    EXPECT_EQ(grid.unit(u).rect, grid.tile(grid.tile_of(u)));
    EXPECT_EQ(grid.unit(u).samples, grid.pass(grid.pass_of(u)));
  }
  EXPECT_EQ(grid.id(2, 1), 5u);
}

TEST(UnitGrid, ARunIsOneTilesConsecutivePassesFoundFromItsSamples) {
  const UnitGrid grid({100, 50}, 64, 10, 4);  // 2 tiles, passes [0,4) [4,8) [8,10)
  EXPECT_EQ(grid.run_samples(1, 1), (SampleRange{0, 4}));
  EXPECT_EQ(grid.run_samples(1, 3), (SampleRange{0, 10}));
  EXPECT_EQ(grid.run_samples(2, 2), (SampleRange{4, 10}));
  // The run of a unit is found from its samples alone, the last (short) pass included.
  EXPECT_EQ(grid.run_covering(0, {0, 4}), 1u);
  EXPECT_EQ(grid.run_covering(0, {0, 8}), 2u);
  EXPECT_EQ(grid.run_covering(1, {0, 10}), 3u);
  EXPECT_EQ(grid.run_covering(3, {4, 10}), 2u);
  EXPECT_EQ(grid.run_covering(5, {8, 10}), 1u);
  for (uint64_t first = 0; first < grid.size(); ++first) {
    for (uint32_t units = 1; units <= grid.pass_count() - grid.pass_of(first); ++units) {
      EXPECT_EQ(grid.run_covering(first, grid.run_samples(first, units)), units);
    }
  }
  // Not a run from that unit: another start, an end inside a pass or past the last, nothing,
  // a unit that does not exist.
  EXPECT_EQ(grid.run_covering(2, {0, 8}), 0u);
  EXPECT_EQ(grid.run_covering(0, {0, 6}), 0u);
  EXPECT_EQ(grid.run_covering(0, {0, 9}), 0u);
  EXPECT_EQ(grid.run_covering(0, {0, 12}), 0u);
  EXPECT_EQ(grid.run_covering(0, {0, 0}), 0u);
  EXPECT_EQ(grid.run_covering(4, {4, 8}), 0u) << "unit 4 is pass 2 of tile 0, which starts at 8";
  EXPECT_EQ(grid.run_covering(6, {0, 4}), 0u);
}

/// A film of `tiles` 1x1 tiles side by side; tile t's samples alternate mean +- spread[t].
struct Strip {
  std::vector<double> spread;
  /// The strip's grid: `passes` passes of pass_spp samples.
  UnitGrid grid(uint32_t passes, uint32_t pass_spp) const {
    return UnitGrid({uint32_t(spread.size()), 1}, 1, passes * pass_spp, pass_spp);
  }
  TileResult unit(uint64_t unit, uint32_t pass_spp) const {
    const uint32_t tile = unit % spread.size(), pass = unit / spread.size();
    TileResult r({tile, 0, tile + 1, 1}, {pass * pass_spp, (pass + 1) * pass_spp});
    for (uint32_t s = 0; s < pass_spp; ++s) {
      const double x = 1.0 + (s % 2 ? spread[tile] : -spread[tile]);
      for (int c = 0; c < 3; ++c) r.sum[c] += to_fixed(x), r.sum_sq[c] += to_fixed(x * x);
    }
    return r;
  }
  /// Merges `u` as the master does: into the film, then the merged record, then the planner.
  void merge(uint64_t u, uint32_t pass_spp, Film& film, MergedUnits& merged,
             PassPlanner& planner) const {
    film.add(unit(u, pass_spp));
    merged.add(u);
    planner.on_merged(u, merged, film);
  }
};

TEST(PassPlanner, WithoutATargetEveryUnitIsNeeded) {
  const Strip strip{{0.1, 0.2}};
  const UnitGrid grid = strip.grid(3, 4);
  PassPlanner planner(grid, {});
  MergedUnits merged(grid);
  EXPECT_FALSE(planner.gated());
  EXPECT_TRUE(planner.take_released().empty());
  EXPECT_EQ(planner.units_released(), 6u);
  Film film(2, 1);
  for (uint64_t u = 0; u < 6; ++u) {
    EXPECT_TRUE(planner.is_released(u));
    EXPECT_FALSE(planner.finished());
    strip.merge(u, 4, film, merged, planner);
  }
  EXPECT_TRUE(planner.finished());
  EXPECT_EQ(planner.reason(), StopReason::kSpp);
  EXPECT_EQ(planner.rounds_complete(merged), 3u);
}

TEST(PassPlanner, QuietTilesStopAndNoisyOnesGoOnOnePassAtATime) {
  // Tile 0 is constant (converges after the minimum), tile 1 never reaches the target.
  const Strip strip{{0.0, 0.5}};
  StopRules rules;
  rules.target_error = 1e-4;
  rules.min_passes = 2;
  const UnitGrid grid = strip.grid(5, 8);
  PassPlanner planner(grid, rules);
  MergedUnits merged(grid);
  ASSERT_TRUE(planner.gated());
  EXPECT_EQ(planner.take_released(), (std::vector<uint64_t>{0, 1, 2, 3}));
  EXPECT_FALSE(planner.is_released(4));
  Film film(2, 1);
  auto merge = [&](uint64_t u) { strip.merge(u, 8, film, merged, planner); };
  merge(2);  // pass 1 of tile 0 before its pass 0: nothing decided yet
  EXPECT_TRUE(planner.take_released().empty());
  merge(0);  // tile 0 has its minimum; budgets wait for every tile's
  EXPECT_TRUE(planner.take_released().empty());
  EXPECT_EQ(planner.tiles_converged(), 0u);
  EXPECT_LT(planner.tile_budget(0), 0.0);
  merge(1);
  merge(3);  // every tile has its minimum: tile 0 (no variance) stops, tile 1 gets pass 2
  EXPECT_EQ(planner.tiles_converged(), 1u);
  EXPECT_EQ(planner.take_released(), (std::vector<uint64_t>{5}));
  // Budgets go as the root of the error and average to the target: 0 for the constant tile,
  // twice the target for the other.
  EXPECT_EQ(planner.tile_budget(0), 0.0);
  EXPECT_DOUBLE_EQ(planner.tile_budget(1), 2 * rules.target_error);
  merge(5);
  EXPECT_EQ(planner.take_released(), (std::vector<uint64_t>{7}));
  merge(7);
  EXPECT_EQ(planner.take_released(), (std::vector<uint64_t>{9}));
  EXPECT_FALSE(planner.finished());
  merge(9);
  EXPECT_TRUE(planner.finished());
  EXPECT_EQ(planner.reason(), StopReason::kSpp);  // tile 1 ran out of passes above the target
  EXPECT_EQ(planner.rounds_complete(merged), 5u);
  EXPECT_GT(planner.tile_error(1), rules.target_error);
}

TEST(PassPlanner, ReachingTheTargetEverywhereIsTheStopReason) {
  const Strip strip{{0.01, 0.02, 0.03}};
  StopRules rules;
  rules.target_error = 1e-3;
  const UnitGrid grid = strip.grid(100, 16);
  PassPlanner planner(grid, rules);
  MergedUnits merged(grid);
  EXPECT_EQ(planner.min_passes(), default_min_passes(16));
  EXPECT_EQ(planner.min_passes(), 16u);
  Film film(3, 1);
  std::vector<uint64_t> ready = planner.take_released();
  while (!ready.empty()) {
    const uint64_t u = ready.back();  // latest first: order must not matter
    ready.pop_back();
    strip.merge(u, 16, film, merged, planner);
    for (uint64_t next : planner.take_released()) ready.push_back(next);
  }
  EXPECT_TRUE(planner.finished());
  EXPECT_EQ(planner.reason(), StopReason::kTargetError);
  EXPECT_EQ(planner.tiles_converged(), 3u);
  EXPECT_LE(estimate_error(film).rel_mse, rules.target_error);
  EXPECT_EQ(film.max_spp(), 256u) << "the minimum passes were already enough";
}

TEST(PassPlanner, NoisierTilesGetLargerBudgetsThatAverageToTheTarget) {
  const Strip strip{{0.01, 0.04, 0.16}};  // errors 1 : 16 : 256
  StopRules rules;
  rules.target_error = 1e-5;
  rules.min_passes = 1;
  const UnitGrid grid = strip.grid(1000, 16);
  PassPlanner planner(grid, rules);
  MergedUnits merged(grid);
  Film film(3, 1);
  for (uint64_t u : planner.take_released()) {
    strip.merge(u, 16, film, merged, planner);
  }
  const double b0 = planner.tile_budget(0), b1 = planner.tile_budget(1),
               b2 = planner.tile_budget(2);
  EXPECT_NEAR(b1 / b0, 4.0, 1e-3);  // sqrt of 16, up to the error's denominator
  EXPECT_NEAR(b2 / b0, 16.0, 2e-2);
  EXPECT_NEAR((b0 + b1 + b2) / 3, rules.target_error, 1e-12);
}

TEST(PassPlanner, WholePassesWaitForTheWholeImage) {
  const Strip strip{{0.0, 0.5}};
  StopRules rules;
  rules.target_error = 1e-4;
  rules.adaptive = false;
  rules.min_passes = 1;
  const UnitGrid grid = strip.grid(3, 8);
  PassPlanner planner(grid, rules);
  MergedUnits merged(grid);
  EXPECT_EQ(planner.take_released(), (std::vector<uint64_t>{0, 1}));
  Film film(2, 1);
  strip.merge(0, 8, film, merged, planner);
  EXPECT_TRUE(planner.take_released().empty()) << "decided before the pass was whole";
  strip.merge(1, 8, film, merged, planner);
  EXPECT_EQ(planner.take_released(), (std::vector<uint64_t>{2, 3}))
      << "the quiet tile goes on with the image";
}

TEST(PassPlanner, AnEstimateKeptByTheCallerGivesTheSameDecisions) {
  // The master keeps the film's estimate tile by tile and hands it to the planner, which then
  // estimates nothing itself: every release and stop must be the one it would have made.
  const Strip strip{{0.01, 0.04, 0.16, 0.0, 0.08}};
  for (const bool adaptive : {true, false}) {
    StopRules rules;
    rules.target_error = 2e-4;
    rules.adaptive = adaptive;
    rules.min_passes = 1;
    const UnitGrid grid = strip.grid(40, 8);
    PassPlanner own(grid, rules), given(grid, rules);
    MergedUnits merged(grid);
    Film film(5, 1);
    TiledErrorEstimate current(grid.tiles());
    std::vector<uint64_t> ready = own.take_released();
    ASSERT_EQ(given.take_released(), ready);
    size_t merges = 0;
    while (!ready.empty()) {
      const uint64_t u = ready.front();
      ready.erase(ready.begin());
      film.add(strip.unit(u, 8));
      merged.add(u);
      current.update(film, grid.tile_of(u));
      own.on_merged(u, merged, film);
      given.on_merged(u, merged, film, &current);
      ++merges;
      const std::vector<uint64_t> next = own.take_released();
      ASSERT_EQ(given.take_released(), next) << "after unit " << u << ", adaptive " << adaptive;
      ready.insert(ready.end(), next.begin(), next.end());
    }
    EXPECT_GT(merges, 5u * 2) << "the target took more than a pass";
    EXPECT_TRUE(own.finished());
    EXPECT_TRUE(given.finished());
    EXPECT_EQ(given.reason(), own.reason());
    for (uint32_t t = 0; t < 5; ++t) EXPECT_EQ(given.tile_error(t), own.tile_error(t));
  }
}

TEST(PassPlanner, ImportedDecisionsMustAgreeWithWhatIsMerged) {
  const Strip strip{{0.0, 0.5}};
  StopRules rules;
  rules.target_error = 1e-4;
  rules.min_passes = 2;
  const UnitGrid grid = strip.grid(5, 8);
  PassPlanner planner(grid, rules);
  MergedUnits merged(grid);
  Film film(2, 1);
  for (uint64_t u : planner.take_released()) {
    strip.merge(u, 8, film, merged, planner);
  }
  // Tile 0 converged after its two passes; tile 1 was given pass 2 (unit 5).
  const PlannerState state = planner.export_state();
  PassPlanner again(grid, rules);
  again.import_state(state, merged);
  EXPECT_TRUE(again.take_released().empty()) << "what to hand out is released and not merged";
  EXPECT_TRUE(again.is_released(5));
  EXPECT_FALSE(again.is_released(4));
  EXPECT_EQ(again.tiles_converged(), 1u);
  EXPECT_EQ(again.rounds_complete(merged), planner.rounds_complete(merged));
  MergedUnits too_many = merged;
  too_many.add(4);  // tile 0's pass 2, never released
  EXPECT_THROW(again.import_state(state, too_many), std::invalid_argument);
  const MergedUnits too_few(grid);  // tile 0 closed with its passes not merged
  EXPECT_THROW(again.import_state(state, too_few), std::invalid_argument);
  EXPECT_EQ(again.tiles_converged(), 1u) << "a refused import changes nothing";
}

TEST(StopReason, Names) {
  EXPECT_STREQ(stop_reason_name(StopReason::kTargetError), "target error");
  EXPECT_STREQ(stop_reason_name(StopReason::kTimeLimit), "time limit");
  EXPECT_STREQ(stop_reason_name(StopReason::kSpp), "spp");
}

TEST(StopRules, OutOfRangeRulesAreRefusedByName) {
  const auto message = [](StopRules rules) -> std::string {
    try {
      check_stop_rules(rules);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(message({}), "");
  EXPECT_EQ(message({1e-3, 1e9}), "");
  EXPECT_EQ(message({1e6, 0}), "target error must be in [0, 1e6), got 1e+06");
  EXPECT_EQ(message({-1, 0}), "target error must be in [0, 1e6), got -1");
  EXPECT_EQ(message({NAN, 0}), "target error must be in [0, 1e6), got nan");
  // Beyond 1e9 s the deadline would overflow the clock's nanoseconds.
  EXPECT_EQ(message({0, 1e12}), "time limit must be in [0, 1e9] s, got 1e+12");
  EXPECT_EQ(message({0, INFINITY}), "time limit must be in [0, 1e9] s, got inf");
}

}  // namespace
}  // namespace rayfarm
