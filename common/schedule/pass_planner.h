#pragma once
// Which units of work a render still needs. A render is a grid of units (unit_grid.h). Without a
// target error every unit is needed. With one, every tile gets its first `min_passes` passes.
// Once all of them are merged, each tile gets its share of the target, its error budget: budgets
// average to the target over the image (weighted by pixels) and are proportional to the square
// root of the tile's error at that point, which spends the fewest samples on reaching the target
// for the image as a whole (a noisy tile needs samples in proportion to its variance to reach a
// fixed error, but only to the root of it to reach its budget). A tile then gets one more pass at
// a time for as long as its estimated relative MSE (error_estimate.h) stays above its budget:
// pass k of a tile is released only once passes 0..k-1 of that tile are merged, and each decision
// reads only those passes (budgets read exactly the first min_passes passes of every tile). Which
// units a render merges is therefore a function of the scene and the settings alone, never of
// timing, so an adaptive farm render still equals the local one bit for bit. Without adaptivity
// (`adaptive = false`) the same decision is made for the whole image after each whole pass. See
// docs/error.md.
//
// The planner owns which units are released. Which are merged it reads from their owner
// (merged_units.h); who holds a lease is the master's scheduler (master/scheduler.h).
#include <cstdint>
#include <vector>

#include "common/image/film.h"
#include "common/schedule/merged_units.h"
#include "common/schedule/stop_rules.h"
#include "common/schedule/unit_grid.h"

namespace rayfarm {

class TiledErrorEstimate;

/// Everything a PassPlanner decided so far, for a checkpoint: decisions read the film at the time
/// they were made, so they cannot be rebuilt from the film afterwards.
struct PlannerState {
  struct Tile {
    uint32_t released = 0;  ///< passes 0..released-1 are released
    bool open = true;       ///< still needs passes
    bool converged = false;
    double error = -1.0;   ///< estimated relMSE at the last decision; negative before the first
    double budget = -1.0;  ///< adaptive: the tile's share of the target; negative until set
    bool operator==(const Tile&) const = default;
  };
  std::vector<Tile> tiles;
  bool operator==(const PlannerState&) const = default;
};

class PassPlanner {
 public:
  /// Plans the units of `grid` (its pass_spp sets the default min_passes).
  PassPlanner(const UnitGrid& grid, const StopRules& rules);

  /// True when units are released as the render goes (a target error is set); otherwise every
  /// unit is needed from the start and take_released() returns nothing.
  bool gated() const { return gated_; }
  /// Units released since the last call, ascending.
  std::vector<uint64_t> take_released();
  /// Unit `unit` was merged into `film` (and recorded in `merged`). Releases the tile's next
  /// pass, or stops the tile. `current`, when given, is the film's estimate over the grid's tiles,
  /// up to date with `film` (the master keeps one): its figures are used instead of estimating
  /// the tile, or the whole image, again.
  void on_merged(uint64_t unit, const MergedUnits& merged, const Film& film,
                 const TiledErrorEstimate* current = nullptr);

  /// Every needed unit is merged.
  bool finished() const { return tiles_open_ == 0; }
  /// Once finished: kTargetError when every tile met the target, else kSpp.
  StopReason reason() const;
  /// The most rounds in which every open tile merged its pass (rounds pace reports).
  uint32_t rounds_complete(const MergedUnits& merged) const;
  uint32_t tile_count() const { return grid_.tile_count(); }
  uint32_t pass_count() const { return grid_.pass_count(); }
  uint32_t tiles_converged() const { return tiles_converged_; }
  uint32_t min_passes() const { return min_passes_; }
  /// True when `unit` has been released (always, for a render that is not gated).
  bool is_released(uint64_t unit) const {
    return grid_.pass_of(unit) < state_[grid_.tile_of(unit)].released;
  }
  /// Units released so far (merged or not).
  uint64_t units_released() const { return units_released_; }
  /// The tile's estimated relative MSE at its last decision; negative before the first.
  double tile_error(uint32_t tile) const { return state_[tile].error; }
  /// The tile's error budget (adaptive renders); negative until every tile has its minimum.
  double tile_budget(uint32_t tile) const { return state_[tile].budget; }

  /// The decisions so far (per tile: released, open, converged, error, budget).
  PlannerState export_state() const;
  /// Replaces the decisions with `state` from a planner of the same grid and rules, `merged`
  /// being what was merged under them. Throws std::invalid_argument naming the inconsistency
  /// (wrong tile count, a unit merged but not released, a closed tile with passes in flight,
  /// ...); the planner is unchanged then. Nothing is left to take_released() afterwards: the
  /// units to hand out are those released and not merged.
  void import_state(const PlannerState& state, const MergedUnits& merged);

 private:
  using TileState = PlannerState::Tile;
  UnitGrid grid_;
  StopRules rules_;
  bool gated_;
  uint32_t min_passes_;
  std::vector<TileState> state_;
  std::vector<uint64_t> released_;
  uint32_t tiles_open_;
  uint32_t tiles_converged_ = 0;
  uint64_t units_released_ = 0;

  void release(uint32_t tile, uint32_t passes);
  void close(uint32_t tile, bool converged);
  /// Every released pass of `tile` is merged.
  bool caught_up(uint32_t tile, const MergedUnits& merged) const {
    return merged.in_tile(tile) == state_[tile].released;
  }
  /// A tile with every released pass merged: stop it, or release its next pass.
  void decide(uint32_t tile);
  /// Sets every tile's budget from its error after the minimum passes.
  void set_budgets();
};

}  // namespace rayfarm
