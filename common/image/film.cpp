#include "common/image/film.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/util/check.h"

namespace rayfarm {

TileResult::TileResult(TileRect r, SampleRange s)
    : rect(r), samples(s), sum(size_t{r.pixel_count()} * 3, 0),
      sum_sq(size_t{r.pixel_count()} * 3, 0) {}

void TileResult::reset(TileRect r, SampleRange s) {
  rect = r;
  samples = s;
  const size_t n = size_t{r.pixel_count()} * 3;
  sum.assign(n, 0);
  sum_sq.assign(n, 0);
  nonfinite = 0;
  rays = 0;
}

bool TileResult::well_formed() const {
  const size_t n = size_t{rect.pixel_count()} * 3;
  return rect.x1 > rect.x0 && rect.y1 > rect.y0 && samples.end > samples.begin &&
         sum.size() == n && sum_sq.size() == n;
}

std::string implausible(const TileResult& r) {
  const uint64_t n = r.samples.count();
  const uint64_t pixels = r.rect.pixel_count();
  if (r.nonfinite > n * pixels) {
    return "it counts " + std::to_string(r.nonfinite) + " non-finite samples of the " +
           std::to_string(n * pixels) + " it covers";
  }
  if (r.rays / kMaxRaysPerSample > n * pixels) {
    return "it counts " + std::to_string(r.rays) + " rays for " + std::to_string(n * pixels) +
           " samples";
  }
  // In fixed-point units (2^-40): a sample v adds trunc(v 2^40) to the sum and trunc(v^2 2^40)
  // to the sum of squares, each off by less than one unit; |v| <= kMaxSampleValue = 2^32. The
  // bounds are integers (the sum of squares' saturates where n 2^104 would not fit); the
  // Cauchy-Schwarz test runs in double with a relative margin of 1e-9, far above double's rounding,
  // so that no possible result is refused (and an impossible one within 1e-9 of possible is
  // harmless).
  const Fixed nn = static_cast<Fixed>(n);
  const Fixed max_sum = nn * (Fixed{1} << 72) + nn;
  const Fixed max_sum_sq = n >= (uint64_t{1} << 22) ? static_cast<Fixed>(~UFixed{0} >> 1)
                                                    : nn * (Fixed{1} << 104) + nn;
  const double dn = static_cast<double>(n);
  const double scale = 1099511627776.0;  // 2^40
  for (size_t i = 0; i < r.sum.size(); ++i) {
    const Fixed sum = r.sum[i], sum_sq = r.sum_sq[i];
    const char* problem = nullptr;
    if (sum_sq < 0) {
      problem = "a negative sum of squares";
    } else if (sum_sq > max_sum_sq) {
      problem = "a sum of squares larger than its samples can reach";
    } else if (sum > max_sum || -sum > max_sum) {
      problem = "a sum larger than its samples can reach";
    } else {
      // (|S| - n)^2 <= n (Q + n) 2^40. Most sums fit 64 bits, whose conversion is cheap.
      auto to_double = [](Fixed v) {
        const auto low = static_cast<int64_t>(v);
        return static_cast<Fixed>(low) == v ? static_cast<double>(low) : static_cast<double>(v);
      };
      const double excess = std::max(0.0, std::fabs(to_double(sum)) - dn);
      if (excess * excess > dn * (to_double(sum_sq) + dn) * scale * (1.0 + 1e-9)) {
        problem = "sum^2 > n * sum of squares (no set of samples has these sums)";
      }
    }
    if (problem) {
      const size_t pixel = i / 3;
      return "pixel (" + std::to_string(r.rect.x0 + pixel % r.rect.width()) + ", " +
             std::to_string(r.rect.y0 + pixel / r.rect.width()) + ") channel " +
             std::to_string(i % 3) + " has " + problem;
    }
  }
  return "";
}

std::vector<TileRect> split_tiles(FilmSize film, uint32_t tile_size) {
  RAYFARM_CHECK(tile_size > 0, "tile size must be positive");
  std::vector<TileRect> tiles;
  for (uint32_t y = 0; y < film.height; y += tile_size) {
    for (uint32_t x = 0; x < film.width; x += tile_size) {
      tiles.push_back({x, y, std::min(x + tile_size, film.width), std::min(y + tile_size, film.height)});
    }
  }
  return tiles;
}

std::vector<SampleRange> split_passes(uint32_t spp, uint32_t pass_spp) {
  RAYFARM_CHECK(pass_spp > 0, "pass size must be positive");
  std::vector<SampleRange> passes;
  for (uint32_t s = 0; s < spp; s += std::min(pass_spp, spp - s)) {
    passes.push_back({s, s + std::min(pass_spp, spp - s)});
  }
  return passes;
}

uint32_t default_pass_spp(uint32_t tile_size, uint32_t spp) {
  const uint64_t pixels = std::max<uint64_t>(1, uint64_t{tile_size} * tile_size);
  const uint64_t target = (uint64_t{1} << 18) / pixels;
  // At least 8 passes where spp allows, so that the error is reported (and tiles may stop)
  // several times in a render. A power of two keeps pass boundaries aligned when spp grows.
  const uint32_t cap = std::max<uint32_t>(spp / 8, 1);
  uint32_t pass = 1;
  while (uint64_t{pass} * 2 <= target && pass * 2 <= cap) pass *= 2;
  return pass;
}

Film::Film(uint32_t width, uint32_t height)
    : width_(width), height_(height), sum_(size_t{width} * height * 3, 0),
      sum_sq_(size_t{width} * height * 3, 0), spp_(size_t{width} * height, 0) {}

bool Film::fits(const TileResult& r) const {
  return r.well_formed() && r.rect.x1 <= width_ && r.rect.y1 <= height_;
}

void Film::add(const TileResult& r) {
  RAYFARM_CHECK(fits(r), "tile result does not fit the film");
  const uint32_t w = r.rect.width();
  for (uint32_t y = r.rect.y0; y < r.rect.y1; ++y) {
    for (uint32_t x = r.rect.x0; x < r.rect.x1; ++x) {
      const size_t src = (size_t{y - r.rect.y0} * w + (x - r.rect.x0)) * 3;
      const size_t dst = (size_t{y} * width_ + x) * 3;
      for (int c = 0; c < 3; ++c) {
        sum_[dst + c] += r.sum[src + c];
        sum_sq_[dst + c] += r.sum_sq[src + c];
      }
      spp_[size_t{y} * width_ + x] += r.samples.count();
    }
  }
  nonfinite_ += r.nonfinite;
  rays_ += r.rays;
}

uint32_t Film::min_spp() const {
  if (spp_.empty()) return 0;
  return *std::min_element(spp_.begin(), spp_.end());
}

uint32_t Film::max_spp() const {
  if (spp_.empty()) return 0;
  return *std::max_element(spp_.begin(), spp_.end());
}

uint64_t Film::pixel_samples() const {
  uint64_t total = 0;
  for (uint32_t n : spp_) total += n;
  return total;
}

std::vector<float> Film::mean_rgb() const {
  std::vector<float> out(sum_.size(), 0.f);
  for (size_t p = 0; p < spp_.size(); ++p) {
    if (spp_[p] == 0) continue;
    for (int c = 0; c < 3; ++c) {
      out[p * 3 + c] = static_cast<float>(from_fixed(sum_[p * 3 + c]) / spp_[p]);
    }
  }
  return out;
}

}  // namespace rayfarm
