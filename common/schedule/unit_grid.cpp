#include "common/schedule/unit_grid.h"

#include "common/util/check.h"

namespace rayfarm {

UnitGrid::UnitGrid(FilmSize film, uint32_t tile_size, uint32_t spp, uint32_t pass_spp)
    : film_(film),
      spp_(spp),
      pass_spp_(pass_spp),
      tiles_(split_tiles(film, tile_size)),
      passes_(split_passes(spp, pass_spp)) {}

UnitGrid::Unit UnitGrid::unit(uint64_t id) const {
  RAYFARM_CHECK(id < size(), "unit number out of range");
  Unit u;
  u.id = id;
  u.pass = pass_of(id);
  u.tile = tile_of(id);
  u.rect = tiles_[u.tile];
  u.samples = passes_[u.pass];
  return u;
}

SampleRange UnitGrid::run_samples(uint64_t first, uint32_t units) const {
  const uint32_t pass = pass_of(first);
  RAYFARM_CHECK(first < size() && units >= 1 && units <= pass_count() - pass,
                "a run past the grid's passes");
  return {passes_[pass].begin, passes_[pass + units - 1].end};
}

uint32_t UnitGrid::run_covering(uint64_t first, const SampleRange& samples) const {
  if (first >= size()) return 0;
  const uint32_t pass = pass_of(first);
  if (samples.begin != passes_[pass].begin || samples.end <= samples.begin) return 0;
  // Every pass but the last has pass_spp_ samples: the run's last pass is found by arithmetic.
  uint32_t last = pass_count() - 1;
  if (samples.end != spp_) {
    if (pass_spp_ == 0 || samples.end % pass_spp_ != 0) return 0;
    last = samples.end / pass_spp_ - 1;
  }
  if (last < pass || last >= pass_count() || passes_[last].end != samples.end) return 0;
  return last - pass + 1;
}

uint64_t UnitGrid::samples_in(uint64_t id) const {
  const Unit u = unit(id);
  return uint64_t{u.rect.pixel_count()} * u.samples.count();
}

uint64_t UnitGrid::samples_total() const { return uint64_t{film_.width} * film_.height * spp_; }

}  // namespace rayfarm
