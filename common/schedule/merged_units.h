#pragma once
// Which units of a render are merged, with a count per tile: the one record of it. The master's
// Merger owns one per job and `rayfarm render` one per render; the pass planner reads it to
// decide, and a checkpoint stores it as one byte per unit.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/schedule/unit_grid.h"

namespace rayfarm {

class MergedUnits {
 public:
  explicit MergedUnits(const UnitGrid& grid)
      : grid_(grid), merged_(grid.size(), false), per_tile_(grid.tile_count(), 0) {}

  bool contains(uint64_t unit) const { return unit < merged_.size() && merged_[unit]; }
  /// Units merged so far.
  uint64_t count() const { return count_; }
  /// Units of tile `tile` merged so far.
  uint32_t in_tile(uint32_t tile) const { return per_tile_[tile]; }
  bool all() const { return count_ == merged_.size(); }

  /// Records `unit` (< grid.size()) as merged; false when it was already.
  bool add(uint64_t unit) {
    if (merged_[unit]) return false;
    merged_[unit] = true;
    ++per_tile_[grid_.tile_of(unit)];
    ++count_;
    return true;
  }

  /// One byte per unit, 1 when merged.
  std::vector<uint8_t> to_bytes() const { return {merged_.begin(), merged_.end()}; }
  /// The units `bytes` (to_bytes() of the same grid) marks merged. Throws std::invalid_argument
  /// when its size is not the grid's.
  static MergedUnits from_bytes(const UnitGrid& grid, const std::vector<uint8_t>& bytes) {
    if (bytes.size() != grid.size()) {
      throw std::invalid_argument(std::to_string(bytes.size()) +
                                  " units in the merged map, the job has " +
                                  std::to_string(grid.size()));
    }
    MergedUnits out(grid);
    for (uint64_t unit = 0; unit < bytes.size(); ++unit) {
      if (bytes[unit]) out.add(unit);
    }
    return out;
  }

 private:
  UnitGrid grid_;
  std::vector<bool> merged_;
  std::vector<uint32_t> per_tile_;
  uint64_t count_ = 0;
};

}  // namespace rayfarm
