#pragma once
// The units of work of one render: every tile for every sample pass. Units are numbered
// pass-major (id(pass, tile) = pass * tiles + tile), so handing them out in number order finishes
// pass 0 over the whole image before pass 1 starts, and the image converges uniformly. The master
// and `rayfarm render` both cut a render with it; nothing else computes a unit's number.
#include <cstdint>
#include <vector>

#include "common/image/film.h"

namespace rayfarm {

class UnitGrid {
 public:
  /// One unit: its number, its pass and tile, the tile's pixels and the sample range.
  struct Unit {
    uint64_t id = 0;
    uint32_t pass = 0;
    uint32_t tile = 0;
    TileRect rect;
    SampleRange samples;
  };

  /// Splits `film` into tiles of at most tile_size and [0, spp) into passes of pass_spp.
  UnitGrid(FilmSize film, uint32_t tile_size, uint32_t spp, uint32_t pass_spp);

  uint64_t size() const { return uint64_t{tiles_.size()} * passes_.size(); }
  uint32_t tile_count() const { return static_cast<uint32_t>(tiles_.size()); }
  uint32_t pass_count() const { return static_cast<uint32_t>(passes_.size()); }
  /// The pass size the grid was cut with (the last pass may be shorter).
  uint32_t pass_spp() const { return pass_spp_; }
  FilmSize film() const { return film_; }
  /// The tiles, as split_tiles(film, tile_size).
  const std::vector<TileRect>& tiles() const { return tiles_; }
  const TileRect& tile(uint32_t tile) const { return tiles_[tile]; }
  const SampleRange& pass(uint32_t pass) const { return passes_[pass]; }

  /// The number of the unit rendering `pass` of `tile`.
  uint64_t id(uint32_t pass, uint32_t tile) const { return uint64_t{pass} * tiles_.size() + tile; }
  /// The tile of unit `id`, as an index into tiles().
  uint32_t tile_of(uint64_t id) const { return static_cast<uint32_t>(id % tiles_.size()); }
  /// The pass of unit `id`.
  uint32_t pass_of(uint64_t id) const { return static_cast<uint32_t>(id / tiles_.size()); }
  /// Unit `id` (CHECKs id < size()).
  Unit unit(uint64_t id) const;
  /// A run: unit `first` and the `units` - 1 units of its tile's next passes (ids first + k x
  /// tile_count()), which one lease may cover and one result sum (the master's scheduler sizes
  /// them). Their samples: from the first pass's begin to the last one's end.
  SampleRange run_samples(uint64_t first, uint32_t units) const;
  /// The units of the run from `first` whose samples are exactly `samples`; 0 when no run of
  /// first's tile starting at first has them (or first is out of range).
  uint32_t run_covering(uint64_t first, const SampleRange& samples) const;
  /// Pixel samples in one unit (pixels of the tile x samples of the pass).
  uint64_t samples_in(uint64_t id) const;
  /// Pixel samples of the whole render.
  uint64_t samples_total() const;
  /// Passes' worth of samples that every pixel has, given the fewest any pixel has: every pass
  /// once it has all spp samples, else whole passes of pass_spp(). A farm job's "pass N/M"
  /// (status, watch, list), while it runs and in its finished record alike. (The master's log and
  /// `rayfarm render`'s progress count rounds of the tiles still open: the pass being rendered.)
  uint32_t passes_within(uint32_t min_spp) const {
    return min_spp >= spp_ ? pass_count() : min_spp / (pass_spp_ > 0 ? pass_spp_ : 1u);
  }

 private:
  FilmSize film_;
  uint32_t spp_;
  uint32_t pass_spp_;
  std::vector<TileRect> tiles_;
  std::vector<SampleRange> passes_;
};

}  // namespace rayfarm
