#pragma once
// Which units of work a render still needs. A render is a grid of units: every tile for every
// sample pass (unit = pass * tiles + tile). Without a target error every unit is needed. With
// one, every tile gets its first `min_passes` passes. Once all of them are merged, each tile gets
// its share of the target, its error budget: budgets average to the target over the image
// (weighted by pixels) and are proportional to the square root of the tile's error at that point,
// which spends the fewest samples on reaching the target for the image as a whole (a noisy tile
// needs samples in proportion to its variance to reach a fixed error, but only to the root of
// it to reach its budget). A tile then gets one more pass at a time for as long as its estimated
// relative MSE (error_estimate.h) stays above its budget: pass k of a tile is released only once
// passes 0..k-1 of that tile are merged, and each decision reads only those passes (budgets read
// exactly the first min_passes passes of every tile). Which units a render merges is therefore a function of the scene and the settings
// alone, never of timing, so an adaptive farm render still equals the local one bit for bit.
// Without adaptivity (`adaptive = false`) the same decision is made for the whole image after
// each whole pass. See docs/error.md.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/image/film.h"

namespace rayfarm {

/// When a render stops besides its spp: the first rule reached ends it.
struct StopRules {
  double target_error = 0.0;  ///< estimated relative MSE; 0 = none
  double time_limit_s = 0.0;  ///< seconds of rendering; 0 = none
  bool adaptive = true;       ///< with a target: stop tile by tile rather than whole passes
  uint32_t min_passes = 0;    ///< passes before a tile may stop; 0 = default_min_passes()
};

/// Throws std::invalid_argument naming the rule and its range when `rules` cannot be followed:
/// a target error outside [0, 1e6) or a time limit outside [0, 1e9] s (or not a number).
void check_stop_rules(const StopRules& rules);

/// Passes a tile gets before its variance estimate is trusted: at least 2, and at least 256
/// samples per pixel. Fewer let the rare paths of caustics go unseen when the error budgets are
/// set (bench/adaptive.sh: with 64 samples, adaptive passes spent more than whole passes).
uint32_t default_min_passes(uint32_t pass_spp);

enum class StopReason { kRunning, kSpp, kTargetError, kTimeLimit, kCancelled, kFailed };
/// "running", "spp", "target error", "time limit", "cancelled", "failed".
const char* stop_reason_name(StopReason reason);

/// Everything a PassPlanner decided so far, for a checkpoint: decisions read the film at the time
/// they were made, so they cannot be rebuilt from the film afterwards.
struct PlannerState {
  struct Tile {
    uint32_t released = 0;  ///< passes 0..released-1 are released
    uint32_t merged = 0;    ///< units of this tile merged
    bool open = true;       ///< still needs passes
    bool converged = false;
    double error = -1.0;    ///< estimated relMSE at the last decision; negative before the first
    double budget = -1.0;   ///< adaptive: the tile's share of the target; negative until set
    bool operator==(const Tile&) const = default;
  };
  std::vector<Tile> tiles;
  std::vector<uint64_t> pending;  ///< released, not yet taken by take_released()
  bool operator==(const PlannerState&) const = default;
};

class PassPlanner {
 public:
  /// `pass_spp` is the size of a full pass (for the default min_passes).
  PassPlanner(std::vector<TileRect> tiles, uint32_t pass_count, uint32_t pass_spp,
              const StopRules& rules);

  /// True when units are released as the render goes (a target error is set); otherwise every
  /// unit is needed from the start and take_released() returns nothing.
  bool gated() const { return gated_; }
  /// Units released since the last call, ascending.
  std::vector<uint64_t> take_released();
  /// Unit `unit` was merged into `film`. Releases the tile's next pass, or stops the tile.
  void on_merged(uint64_t unit, const Film& film);

  /// Every needed unit is merged.
  bool finished() const { return tiles_open_ == 0; }
  /// Once finished: kTargetError when every tile met the target, else kSpp.
  StopReason reason() const;
  /// The most leading rounds in which every open tile merged its pass (rounds pace reports).
  uint32_t rounds_complete() const;
  uint32_t tile_count() const { return static_cast<uint32_t>(tiles_.size()); }
  uint32_t pass_count() const { return pass_count_; }
  uint32_t tiles_converged() const { return tiles_converged_; }
  uint32_t min_passes() const { return min_passes_; }
  /// True when `unit` has been released (always, for a render that is not gated).
  bool is_released(uint64_t unit) const {
    return unit / tiles_.size() < state_[unit % tiles_.size()].released;
  }
  /// Units released so far (merged or not).
  uint64_t units_released() const { return units_released_; }
  /// The tile's estimated relative MSE at its last decision; negative before the first.
  double tile_error(uint32_t tile) const { return state_[tile].error; }
  /// The tile's error budget (adaptive renders); negative until every tile has its minimum.
  double tile_budget(uint32_t tile) const { return state_[tile].budget; }

  /// The decisions so far (per tile: released, merged, open, converged, error).
  PlannerState export_state() const;
  /// Replaces the decisions with `state` from a planner of the same tiles, passes and rules.
  /// Throws std::invalid_argument naming the inconsistency (wrong tile count, more passes merged
  /// than released, a closed tile with passes in flight, ...); the planner is unchanged then.
  void import_state(const PlannerState& state);

 private:
  using TileState = PlannerState::Tile;
  std::vector<TileRect> tiles_;
  uint32_t pass_count_;
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
  /// A tile with every released pass merged: stop it, or release its next pass.
  void decide(uint32_t tile);
  /// Sets every tile's budget from its error after the minimum passes.
  void set_budgets();
};

}  // namespace rayfarm
