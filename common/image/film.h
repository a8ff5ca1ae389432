#pragma once
// The unit of work (a tile rectangle and a sample range), its result, and the film that merges
// results. Sums are exact fixed-point numbers (fixed.h), so merging is associative: any grouping
// of samples into passes and any order of arrival gives the same bits (docs/determinism.md).
#include <cstdint>
#include <vector>

#include "common/image/fixed.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// Half-open pixel rectangle [x0, x1) x [y0, y1).
struct TileRect {
  uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  uint32_t width() const { return x1 - x0; }
  uint32_t height() const { return y1 - y0; }
  uint32_t pixel_count() const { return width() * height(); }
  bool operator==(const TileRect&) const = default;
};

/// Half-open range of sample indices [begin, end) within each pixel.
struct SampleRange {
  uint32_t begin = 0, end = 0;
  uint32_t count() const { return end - begin; }
  bool operator==(const SampleRange&) const = default;
};

/// Per-pixel sums of one unit of work, row-major over `rect`, 3 values (RGB) per pixel.
struct TileResult {
  TileRect rect;
  SampleRange samples;
  std::vector<Fixed> sum;      ///< sum of sample radiance
  std::vector<Fixed> sum_sq;   ///< sum of squared sample radiance (for variance)
  uint64_t nonfinite = 0;      ///< samples dropped: NaN, infinite, or above kMaxSampleValue
  uint64_t rays = 0;           ///< rays traced (closest-hit and shadow)

  /// Allocates zeroed sums for `rect`.
  TileResult(TileRect r, SampleRange s);
  TileResult() = default;
  /// Makes this the empty result of (r, s): zeroed sums and counts, in the buffers it already
  /// has where they are large enough. A unit's sums are 96 bytes a pixel; allocated afresh for
  /// every unit, they would come back from the kernel as new pages, faulted in one by one.
  void reset(TileRect r, SampleRange s);
  bool well_formed() const;
};

/// Most rays one sample can trace: a camera or bounce ray and a shadow ray per vertex, up to the
/// largest path depth a job may ask for (1024), with room to spare.
inline constexpr uint64_t kMaxRaysPerSample = 4096;

/// Why the sums of a well-formed result cannot come from its samples, or "" when they can. Every
/// check is exact for what the renderer produces (film.cpp says how): the non-finite count is at
/// most the samples taken; per pixel and channel the sum of squares is not negative and at most
/// n times the largest square a sample may add, the sum at most n times the largest sample
/// (kMaxSampleValue), and sum^2 <= n * sum_sq (Cauchy-Schwarz) within the fixed-point rounding
/// of n truncations; the rays at most kMaxRaysPerSample per sample.
std::string implausible(const TileResult& result);

/// Splits the image into tiles of at most tile_size x tile_size, row by row.
std::vector<TileRect> split_tiles(FilmSize film, uint32_t tile_size);
/// Splits [0, spp) into passes of pass_spp samples (the last may be shorter).
std::vector<SampleRange> split_passes(uint32_t spp, uint32_t pass_spp);
/// Pass size used when none is given: about 2^18 samples per unit for this tile size, at most
/// spp / 8 (so a render has about 8 passes or more), a power of two. The image does not depend
/// on it.
uint32_t default_pass_spp(uint32_t tile_size, uint32_t spp);

/// Accumulates unit results exactly, in any order. Results that overlap are the caller's bug.
class Film {
 public:
  Film(uint32_t width, uint32_t height);

  /// True when `r` is well formed and lies inside the film.
  bool fits(const TileResult& r) const;
  /// Adds a result; CHECKs fits(r).
  void add(const TileResult& r);

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  /// Samples merged so far in pixel (x, y).
  uint32_t spp_at(uint32_t x, uint32_t y) const { return spp_[y * width_ + x]; }
  /// Fewest and most samples of any pixel (they differ when tiles stop adaptively).
  uint32_t min_spp() const;
  uint32_t max_spp() const;
  /// Pixel samples merged so far, over the whole film.
  uint64_t pixel_samples() const;
  uint64_t nonfinite() const { return nonfinite_; }
  uint64_t rays() const { return rays_; }
  const std::vector<Fixed>& sum() const { return sum_; }
  const std::vector<Fixed>& sum_sq() const { return sum_sq_; }
  const std::vector<uint32_t>& spp() const { return spp_; }

  /// Current estimate (mean radiance), RGB float32 row-major; 0 where no sample yet.
  std::vector<float> mean_rgb() const;

 private:
  uint32_t width_, height_;
  std::vector<Fixed> sum_, sum_sq_;
  std::vector<uint32_t> spp_;
  uint64_t nonfinite_ = 0;
  uint64_t rays_ = 0;
};

}  // namespace rayfarm
