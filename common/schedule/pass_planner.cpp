#include "common/schedule/pass_planner.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/image/error_estimate.h"
#include "common/util/check.h"

namespace rayfarm {

PassPlanner::PassPlanner(const UnitGrid& grid, const StopRules& rules)
    : grid_(grid),
      rules_(rules),
      gated_(rules.target_error > 0),
      min_passes_(std::min(grid.pass_count(), rules.min_passes > 0
                                                  ? rules.min_passes
                                                  : default_min_passes(grid.pass_spp()))),
      state_(grid.tile_count()),
      tiles_open_(grid.tile_count()) {
  RAYFARM_CHECK(grid.size() > 0, "a render needs at least one unit");
  if (!gated_) {
    for (TileState& s : state_) s.released = pass_count();
    units_released_ = grid_.size();
    return;
  }
  // The first passes of every tile, pass-major.
  for (uint32_t p = 0; p < min_passes_; ++p) {
    for (uint32_t t = 0; t < tile_count(); ++t) release(t, 1);
  }
}

void PassPlanner::release(uint32_t tile, uint32_t passes) {
  TileState& s = state_[tile];
  for (uint32_t i = 0; i < passes && s.released < pass_count(); ++i) {
    released_.push_back(grid_.id(s.released, tile));
    ++s.released;
    ++units_released_;
  }
}

std::vector<uint64_t> PassPlanner::take_released() {
  std::vector<uint64_t> out;
  out.swap(released_);
  std::sort(out.begin(), out.end());
  return out;
}

void PassPlanner::close(uint32_t tile, bool converged) {
  TileState& s = state_[tile];
  if (!s.open) return;
  s.open = false;
  s.converged = converged;
  --tiles_open_;
  if (converged) ++tiles_converged_;
}

void PassPlanner::on_merged(uint64_t unit, const MergedUnits& merged, const Film& film,
                            const TiledErrorEstimate* current) {
  const uint32_t tile = grid_.tile_of(unit);
  TileState& s = state_[tile];
  RAYFARM_CHECK(s.open && is_released(unit) && merged.contains(unit),
                "merged a unit the planner did not release");
  RAYFARM_CHECK(!current || current->tiles().size() == tile_count(),
                "the estimate given to the planner is not over its tiles");
  if (!caught_up(tile, merged)) return;  // the tile still has released passes in flight

  if (!gated_) {
    close(tile, false);
    return;
  }
  if (rules_.adaptive) {
    s.error =
        current ? current->tile(tile).rel_mse : estimate_error(film, grid_.tile(tile)).rel_mse;
    if (s.budget >= 0) {
      decide(tile);
      return;
    }
    // Budgets wait until every tile has merged its minimum passes (and nothing more).
    for (uint32_t t = 0; t < tile_count(); ++t) {
      if (!caught_up(t, merged) || state_[t].error < 0) return;
    }
    set_budgets();
    for (uint32_t t = 0; t < tile_count(); ++t) decide(t);
    return;
  }
  // Whole passes: decide once every tile has merged what it was given.
  for (uint32_t t = 0; t < tile_count(); ++t) {
    if (!caught_up(t, merged)) return;
  }
  // The image's figure as the render reports it: the pixel-weighted mean of the tiles'.
  double error = 0;
  if (current) {
    error = current->whole().rel_mse;
  } else {
    TiledErrorEstimate image(grid_.tiles());
    image.update_all(film);
    error = image.whole().rel_mse;
  }
  for (uint32_t t = 0; t < tile_count(); ++t) {
    state_[t].error = error;
    if (error <= rules_.target_error) {
      close(t, true);
    } else if (state_[t].released == pass_count()) {
      close(t, false);
    } else {
      release(t, 1);
    }
  }
}

void PassPlanner::decide(uint32_t tile) {
  const TileState& s = state_[tile];
  if (s.error <= s.budget) {
    close(tile, true);
  } else if (s.released == pass_count()) {
    close(tile, false);
  } else {
    release(tile, 1);
  }
}

void PassPlanner::set_budgets() {
  // Budget_t = target * sqrt(e_t) * sum(pixels) / sum(pixels * sqrt(e))): the budgets average to
  // the target, and the samples a tile needs to reach its budget, proportional to e_t / budget_t,
  // go as sqrt(e_t): the least total for the image's target (Neyman allocation).
  double pixels = 0, weighted = 0;
  bool finite = true;
  for (uint32_t t = 0; t < tile_count(); ++t) {
    const double e = state_[t].error;
    finite = finite && std::isfinite(e);
    pixels += grid_.tile(t).pixel_count();
    weighted += grid_.tile(t).pixel_count() * std::sqrt(std::max(e, 0.0));
  }
  for (uint32_t t = 0; t < tile_count(); ++t) {
    TileState& s = state_[t];
    if (!finite || weighted <= 0) {
      s.budget = rules_.target_error;  // no usable estimate: the same share for all
    } else {
      s.budget = rules_.target_error * std::sqrt(std::max(s.error, 0.0)) * pixels / weighted;
    }
  }
}

PlannerState PassPlanner::export_state() const {
  PlannerState out;
  out.tiles = state_;
  return out;
}

void PassPlanner::import_state(const PlannerState& state, const MergedUnits& merged) {
  auto fail = [](const std::string& why) { throw std::invalid_argument("planner state: " + why); };
  if (state.tiles.size() != tile_count()) {
    fail(std::to_string(state.tiles.size()) + " tiles, the render has " +
         std::to_string(tile_count()));
  }
  uint32_t open = 0, converged = 0;
  uint64_t released = 0;
  for (uint32_t t = 0; t < tile_count(); ++t) {
    const TileState& s = state.tiles[t];
    const std::string where = "tile " + std::to_string(t) + ": ";
    if (s.released > pass_count()) fail(where + "more passes released than the render has");
    for (uint32_t p = s.released; p < pass_count(); ++p) {
      if (merged.contains(grid_.id(p, t))) {
        fail("unit " + std::to_string(grid_.id(p, t)) + " is merged but not released");
      }
    }
    if (!gated_ && s.released != pass_count())
      fail(where + "an ungated render releases every pass");
    if (gated_ && s.released < min_passes_) fail(where + "fewer passes released than the minimum");
    if (!s.open && merged.in_tile(t) != s.released) fail(where + "closed with passes in flight");
    if (s.converged && s.open) fail(where + "converged but open");
    open += s.open ? 1 : 0;
    converged += s.converged ? 1 : 0;
    released += s.released;
  }
  state_ = state.tiles;
  released_.clear();
  tiles_open_ = open;
  tiles_converged_ = converged;
  units_released_ = released;
}

StopReason PassPlanner::reason() const {
  if (!finished()) return StopReason::kRunning;
  return gated_ && tiles_converged_ == tile_count() ? StopReason::kTargetError : StopReason::kSpp;
}

uint32_t PassPlanner::rounds_complete(const MergedUnits& merged) const {
  uint32_t rounds = pass_count();
  for (uint32_t t = 0; t < tile_count(); ++t) {
    if (state_[t].open) rounds = std::min(rounds, merged.in_tile(t));
  }
  return rounds;
}

}  // namespace rayfarm
