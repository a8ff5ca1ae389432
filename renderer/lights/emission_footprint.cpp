#include "renderer/lights/emission_footprint.h"

#include <algorithm>
#include <cmath>
#include <variant>

namespace rayfarm {
namespace {

constexpr uint64_t kMaxCells = uint64_t{1} << 20;

/// A column (or row) range of the image, inclusive.
struct Span {
  int64_t lo, hi;
};

/// The texel indices that indices [i0, i1] of the unwrapped image read under `wrap` (as
/// ImageTexture's wrap_index maps them), as at most two ranges inside [0, n).
int wrap_spans(int64_t i0, int64_t i1, int64_t n, TextureWrap wrap, Span (&out)[2]) {
  const auto floor_div = [](int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); };
  switch (wrap) {
    case TextureWrap::clamp:
      out[0] = {std::clamp<int64_t>(i0, 0, n - 1), std::clamp<int64_t>(i1, 0, n - 1)};
      return 1;
    case TextureWrap::repeat: {
      if (i1 - i0 + 1 >= n) break;
      const int64_t a = i0 - floor_div(i0, n) * n, b = a + (i1 - i0);
      if (b < n) {
        out[0] = {a, b};
        return 1;
      }
      out[0] = {a, n - 1};
      out[1] = {0, b - n};
      return 2;
    }
    case TextureWrap::mirror: {
      // Within one period of the image, forwards or mirrored; across a turn, all of it.
      const int64_t k = floor_div(i0, n);
      if (floor_div(i1, n) != k) break;
      const int64_t a = i0 - k * n, b = i1 - k * n;
      out[0] = k % 2 == 0 ? Span{a, b} : Span{n - 1 - b, n - 1 - a};
      return 1;
    }
  }
  out[0] = {0, n - 1};
  return 1;
}

/// The texel index range that lookups at image coordinates within [lo, hi] (in texels) read: the
/// nearest texel or the four around a point, widened by `margin` texels for rounding.
Span reach(double lo, double hi, double margin) {
  return {static_cast<int64_t>(std::floor(lo - 0.5 - margin)),
          static_cast<int64_t>(std::floor(hi - 0.5 + margin)) + 1};
}

}  // namespace

EmissionFootprints::EmissionFootprints(const Scene& scene, const TextureSet& textures) {
  for (const Material& m : scene.materials) {
    const int32_t t = m.emission.texture;
    if (t < 0 || tables_.count(t) != 0) continue;
    if (const auto* image = std::get_if<ImageTexture>(&textures.texture(uint32_t(t))))
      tables_.emplace(t, build(image->image(), image->options()));
  }
}

EmissionFootprints::Table EmissionFootprints::build(const TexelImage& image,
                                                    const ImageTextureOptions& options) {
  Table t;
  t.width = image.width(), t.height = image.height();
  t.options = options;
  t.map = UvMap(options.transform);
  while (uint64_t((t.width + t.block - 1) / t.block) * ((t.height + t.block - 1) / t.block) >
         kMaxCells)
    ++t.block;
  t.cw = (t.width + t.block - 1) / t.block, t.ch = (t.height + t.block - 1) / t.block;
  const size_t stride = size_t{t.cw} + 1;
  t.count.assign(stride * (t.ch + 1), 0);
  t.sum.assign(stride * (t.ch + 1), 0.0);
  // Each cell's own count and sum at (cx + 1, cy + 1), then the prefix sums in place.
  for (uint32_t y = 0; y < t.height; ++y) {
    for (uint32_t x = 0; x < t.width; ++x) {
      const Vec4 c = image.texel(x, y);
      const auto positive = [](float v) { return v > 0.f ? std::min(double(v), 1e30) : 0.0; };
      const double r = positive(c.x), g = positive(c.y), b = positive(c.z);
      if (r == 0.0 && g == 0.0 && b == 0.0) continue;
      const size_t at = (size_t{y / t.block} + 1) * stride + x / t.block + 1;
      ++t.count[at];
      t.sum[at] += 0.2126 * r + 0.7152 * g + 0.0722 * b;
    }
  }
  for (size_t y = 1; y <= t.ch; ++y) {
    for (size_t x = 1; x <= t.cw; ++x) {
      const size_t at = y * stride + x;
      t.count[at] += t.count[at - 1] + t.count[at - stride] - t.count[at - stride - 1];
      t.sum[at] += t.sum[at - 1] + t.sum[at - stride] - t.sum[at - stride - 1];
    }
  }
  return t;
}

void EmissionFootprints::add_rect(const Table& t, int64_t x0, int64_t x1, int64_t y0, int64_t y1,
                                  Sums& out) {
  const int64_t b = t.block;
  const size_t bx0 = size_t(x0 / b), bx1 = size_t(x1 / b) + 1, by0 = size_t(y0 / b),
               by1 = size_t(y1 / b) + 1;
  const size_t stride = size_t{t.cw} + 1;
  const auto at = [&](size_t x, size_t y) { return y * stride + x; };
  // The count is exact (integers); the sum only weighs the light, and is kept non-negative.
  out.count += t.count[at(bx1, by1)] - t.count[at(bx0, by1)] - t.count[at(bx1, by0)] +
               t.count[at(bx0, by0)];
  out.sum += std::max(
      0.0, t.sum[at(bx1, by1)] - t.sum[at(bx0, by1)] - t.sum[at(bx1, by0)] + t.sum[at(bx0, by0)]);
  const int64_t w = std::min<int64_t>(int64_t(bx1) * b, t.width) - int64_t(bx0) * b;
  const int64_t h = std::min<int64_t>(int64_t(by1) * b, t.height) - int64_t(by0) * b;
  out.texels += double(w) * double(h);
}

std::optional<TexelFootprint> EmissionFootprints::find(int32_t texture,
                                                       const Vec2 (&uv)[3]) const {
  const auto it = tables_.find(texture);
  if (it == tables_.end()) return std::nullopt;
  const Table& t = it->second;
  // The corners in image texels, unwrapped: x to the right, y down from the top row.
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, largest = 0.0;
  bool finite = true;
  for (const Vec2& c : uv) {
    const auto [tu, tv] = t.map.apply(c.x, c.y);
    const double p[2] = {tu * t.width,
                         (t.options.origin == UvOrigin::bottom_left ? 1.0 - tv : tv) * t.height};
    for (int a = 0; a < 2; ++a) {
      lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
      largest = std::max(largest, std::fabs(p[a]));
      finite = finite && std::isfinite(p[a]);
    }
  }
  Span xs[2], ys[2];
  int nx = 1, ny = 1;
  // Coordinates interpolated in float inside the triangle may stray a few ulps beyond its
  // corners: a margin of a texel plus a millionth of their size. Beyond 2^40 texels (or not
  // finite), the whole image.
  if (!finite || !(largest < 0x1p40)) {
    xs[0] = {0, int64_t(t.width) - 1}, ys[0] = {0, int64_t(t.height) - 1};
  } else {
    const double margin = 1.0 + largest * 1e-6;
    const Span x = reach(lo[0], hi[0], margin), y = reach(lo[1], hi[1], margin);
    nx = wrap_spans(x.lo, x.hi, t.width, t.options.wrap_u, xs);
    ny = wrap_spans(y.lo, y.hi, t.height, t.options.wrap_v, ys);
  }
  Sums s;
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) add_rect(t, xs[i].lo, xs[i].hi, ys[j].lo, ys[j].hi, s);
  TexelFootprint out;
  out.black = s.count == 0;
  out.mean_luminance = s.texels > 0.0 ? s.sum / s.texels : 0.0;
  return out;
}

}  // namespace rayfarm
