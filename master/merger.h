#pragma once
// Merges the results of one job into its Film, each unit exactly once. A result is checked against
// the unit it claims to be (tile, sample range, sizes) before Film::add, which CHECKs; a second
// result for a merged unit is a duplicate and is dropped. The merger owns which units are merged
// (merged_units()): the planner and the job manager read it from here. The film's fixed-point sums
// make the image independent of the order of arrival (common/image/film.h).
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/image/film.h"
#include "common/schedule/merged_units.h"
#include "common/schedule/unit_grid.h"

namespace rayfarm::master {

enum class MergeOutcome {
  kMerged,     ///< added to the film
  kDuplicate,  ///< the unit was merged before; the result is dropped
  kRejected,   ///< the result does not match its unit, or its sums are impossible; nothing is added
  kUnleased,   ///< the sender was never leased the unit; dropped, counted against nobody
  kDiscarded,  ///< its job was cancelled or failed: a late result, routine, dropped (the job
               ///< manager's; the merger never returns it)
};

class Merger {
 public:
  explicit Merger(UnitGrid grid);

  /// Whether `rect` and `samples` are exactly those of the run of `units` units from `unit`
  /// (UnitGrid::run_samples; one unit by default), all existing; when not, `why` (when given)
  /// names the mismatch. A result's tile sizes the decoding of its sums, so the master checks it
  /// with this before decoding; add() checks it again.
  bool covers(uint64_t unit, const TileRect& rect, const SampleRange& samples,
              std::string* why = nullptr, uint32_t units = 1) const;
  /// Merges `result` as the run of `units` units from `unit` (one by default): its sums are the
  /// sums of those units' samples. kDuplicate when any of them was merged before (nothing is
  /// added: the sums cannot be split). On kRejected, `why` (when given) names the mismatch.
  MergeOutcome add(uint64_t unit, const TileResult& result, std::string* why = nullptr,
                   uint32_t units = 1);

  bool merged(uint64_t unit) const { return merged_.contains(unit); }
  uint64_t merged_count() const { return merged_.count(); }
  bool complete() const { return merged_.all(); }
  /// The units merged so far.
  const MergedUnits& merged_units() const { return merged_; }
  /// Pixel samples merged so far.
  uint64_t samples_merged() const { return samples_merged_; }
  /// Fewest samples of any pixel: the film's min_spp(), from the tiles (O(tiles), not O(pixels);
  /// every pixel of a tile has the tile's samples).
  uint32_t min_spp() const;
  /// The film, allocated on first use: a queued job (a sequence's later frames) holds no pixels.
  const Film& film() const;
  const UnitGrid& grid() const { return grid_; }
  /// Replaces what is merged with a checkpoint's state: the merged units (one byte per unit,
  /// MergedUnits::to_bytes) and the film's sums. The film is rebuilt tile by tile, each pixel
  /// with the samples of its tile's merged units; a tile with none must have zero sums. Throws
  /// std::invalid_argument naming the inconsistency; the merger is unchanged then.
  void restore(const std::vector<uint8_t>& merged, const std::vector<Fixed>& sum,
               const std::vector<Fixed>& sum_sq, uint64_t nonfinite, uint64_t rays);

 private:
  UnitGrid grid_;
  mutable std::optional<Film> film_;  // film()
  MergedUnits merged_;
  std::vector<uint32_t> tile_spp_;  // samples per pixel merged in each tile
  uint64_t samples_merged_ = 0;
};

}  // namespace rayfarm::master
