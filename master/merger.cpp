#include "master/merger.h"

namespace rayfarm::master {
namespace {

std::string describe(const TileRect& r, const SampleRange& s) {
  return "tile [" + std::to_string(r.x0) + "," + std::to_string(r.x1) + ")x[" +
         std::to_string(r.y0) + "," + std::to_string(r.y1) + ") samples [" +
         std::to_string(s.begin) + "," + std::to_string(s.end) + ")";
}

}  // namespace

Merger::Merger(UnitGrid grid)
    : grid_(std::move(grid)),
      film_(grid_.film().width, grid_.film().height),
      merged_(grid_.size(), false),
      merged_per_pass_(grid_.pass_count(), 0) {}

MergeOutcome Merger::add(uint64_t unit, const TileResult& result, std::string* why) {
  auto reject = [&](const std::string& reason) {
    if (why) *why = reason;
    return MergeOutcome::kRejected;
  };
  if (unit >= grid_.size()) {
    return reject("unit " + std::to_string(unit) + " does not exist (the job has " +
                  std::to_string(grid_.size()) + " units)");
  }
  if (merged_[unit]) return MergeOutcome::kDuplicate;
  const UnitGrid::Unit expected = grid_.unit(unit);
  if (!(result.rect == expected.rect) || !(result.samples == expected.samples)) {
    return reject("unit " + std::to_string(unit) + " is " +
                  describe(expected.rect, expected.samples) + ", the result covers " +
                  describe(result.rect, result.samples));
  }
  if (!result.well_formed() || !film_.fits(result)) {
    return reject("unit " + std::to_string(unit) + ": malformed sums (" +
                  std::to_string(result.sum.size()) + " and " +
                  std::to_string(result.sum_sq.size()) + " values for " +
                  std::to_string(result.rect.pixel_count()) + " pixels)");
  }
  film_.add(result);
  merged_[unit] = true;
  ++merged_count_;
  ++merged_per_pass_[expected.pass];
  samples_merged_ += uint64_t{expected.rect.pixel_count()} * expected.samples.count();
  return MergeOutcome::kMerged;
}

uint32_t Merger::passes_complete() const {
  uint32_t passes = 0;
  while (passes < merged_per_pass_.size() && merged_per_pass_[passes] == grid_.tile_count())
    ++passes;
  return passes;
}

}  // namespace rayfarm::master
