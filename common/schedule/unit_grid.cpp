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

uint64_t UnitGrid::samples_in(uint64_t id) const {
  const Unit u = unit(id);
  return uint64_t{u.rect.pixel_count()} * u.samples.count();
}

uint64_t UnitGrid::samples_total() const { return uint64_t{film_.width} * film_.height * spp_; }

}  // namespace rayfarm
