#include "master/merger.h"

#include <algorithm>
#include <stdexcept>

namespace rayfarm::master {
namespace {

std::string describe(const TileRect& r, const SampleRange& s) {
  return "tile [" + std::to_string(r.x0) + "," + std::to_string(r.x1) + ")x[" +
         std::to_string(r.y0) + "," + std::to_string(r.y1) + ") samples [" +
         std::to_string(s.begin) + "," + std::to_string(s.end) + ")";
}

}  // namespace

Merger::Merger(UnitGrid grid)
    : grid_(std::move(grid)), merged_(grid_), tile_spp_(grid_.tile_count(), 0) {}

const Film& Merger::film() const {
  if (!film_) film_.emplace(grid_.film().width, grid_.film().height);
  return *film_;
}

bool Merger::covers(uint64_t unit, const TileRect& rect, const SampleRange& samples,
                    std::string* why, uint32_t units) const {
  std::string reason;
  if (unit >= grid_.size()) {
    reason = "unit " + std::to_string(unit) + " does not exist (the job has " +
             std::to_string(grid_.size()) + " units)";
  } else if (units == 0 || units > grid_.pass_count() - grid_.pass_of(unit)) {
    reason = "unit " + std::to_string(unit) + " has no run of " + std::to_string(units) +
             " units (pass " + std::to_string(grid_.pass_of(unit)) + " of " +
             std::to_string(grid_.pass_count()) + ")";
  } else if (const SampleRange run = grid_.run_samples(unit, units);
             !(rect == grid_.tile(grid_.tile_of(unit))) || !(samples == run)) {
    reason = (units == 1
                  ? "unit " + std::to_string(unit)
                  : "the run of " + std::to_string(units) + " units from " + std::to_string(unit)) +
             " is " + describe(grid_.tile(grid_.tile_of(unit)), run) + ", the result covers " +
             describe(rect, samples);
  } else {
    return true;
  }
  if (why) *why = reason;
  return false;
}

MergeOutcome Merger::add(uint64_t unit, const TileResult& result, std::string* why,
                         uint32_t units) {
  auto reject = [&](const std::string& reason) {
    if (why) *why = reason;
    return MergeOutcome::kRejected;
  };
  if (unit < grid_.size() && merged_.contains(unit)) return MergeOutcome::kDuplicate;
  if (!covers(unit, result.rect, result.samples, why, units)) return MergeOutcome::kRejected;
  const uint64_t stride = grid_.tile_count();
  for (uint32_t k = 1; k < units; ++k) {
    if (merged_.contains(unit + k * stride)) return MergeOutcome::kDuplicate;
  }
  if (!result.well_formed() || !film().fits(result)) {
    return reject("unit " + std::to_string(unit) + ": malformed sums (" +
                  std::to_string(result.sum.size()) + " and " +
                  std::to_string(result.sum_sq.size()) + " values for " +
                  std::to_string(result.rect.pixel_count()) + " pixels)");
  }
  if (const std::string problem = implausible(result); !problem.empty()) {
    return reject("unit " + std::to_string(unit) + ": impossible sums: " + problem);
  }
  film_->add(result);
  for (uint32_t k = 0; k < units; ++k) merged_.add(unit + k * stride);
  tile_spp_[grid_.tile_of(unit)] += result.samples.count();
  samples_merged_ += uint64_t{result.rect.pixel_count()} * result.samples.count();
  return MergeOutcome::kMerged;
}

void Merger::restore(const std::vector<uint8_t>& merged, const std::vector<Fixed>& sum,
                     const std::vector<Fixed>& sum_sq, uint64_t nonfinite, uint64_t rays) {
  auto fail = [](const std::string& why) { throw std::invalid_argument(why); };
  const FilmSize size = grid_.film();
  const size_t pixels = size_t{size.width} * size.height;
  MergedUnits units = MergedUnits::from_bytes(grid_, merged);
  if (sum.size() != pixels * 3 || sum_sq.size() != pixels * 3) {
    fail("the sums do not match the film's size");
  }
  std::vector<uint32_t> tile_spp(grid_.tile_count(), 0);
  uint64_t samples = 0;
  for (uint64_t unit = 0; unit < grid_.size(); ++unit) {
    if (!units.contains(unit)) continue;
    const UnitGrid::Unit u = grid_.unit(unit);
    tile_spp[u.tile] += u.samples.count();
    samples += uint64_t{u.rect.pixel_count()} * u.samples.count();
  }
  Film film(size.width, size.height);
  bool totals_added = false;
  for (uint32_t t = 0; t < grid_.tile_count(); ++t) {
    const TileRect rect = grid_.tile(t);
    TileResult r(rect, {0, tile_spp[t]});
    for (uint32_t y = rect.y0; y < rect.y1; ++y) {
      for (uint32_t x = rect.x0; x < rect.x1; ++x) {
        const size_t p = size_t{y} * size.width + x;
        const size_t src = (size_t{y - rect.y0} * rect.width() + (x - rect.x0)) * 3;
        for (int c = 0; c < 3; ++c) {
          r.sum[src + c] = sum[p * 3 + c];
          r.sum_sq[src + c] = sum_sq[p * 3 + c];
          if (tile_spp[t] == 0 && (sum[p * 3 + c] != 0 || sum_sq[p * 3 + c] != 0)) {
            fail("pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                 ") has sums but no merged unit");
          }
        }
      }
    }
    if (tile_spp[t] == 0) continue;
    if (!totals_added) {
      r.nonfinite = nonfinite;
      r.rays = rays;
      totals_added = true;
    }
    film.add(r);
  }
  if (!totals_added && (nonfinite != 0 || rays != 0)) fail("rays counted but no unit merged");
  film_.emplace(std::move(film));
  merged_ = std::move(units);
  tile_spp_ = std::move(tile_spp);
  samples_merged_ = samples;
}

uint32_t Merger::min_spp() const {
  return tile_spp_.empty() ? 0 : *std::min_element(tile_spp_.begin(), tile_spp_.end());
}

}  // namespace rayfarm::master
