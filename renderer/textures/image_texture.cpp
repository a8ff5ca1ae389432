#include "renderer/textures/image_texture.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rayfarm {
namespace {

/// `s` (image coordinates in [0, 1) per period) brought into one or two periods, so that texel
/// indices stay small whatever the UVs; the lookup is unchanged (repeat has period 1, mirror 2,
/// and clamp extends the edge anyway).
double reduce(double s, TextureWrap wrap) {
  if (!std::isfinite(s)) return 0.0;
  switch (wrap) {
    case TextureWrap::repeat:
      return s - std::floor(s);
    case TextureWrap::mirror:
      return s - 2.0 * std::floor(s / 2.0);
    case TextureWrap::clamp:
      return std::clamp(s, -1.0, 2.0);
  }
  return s;
}

/// Texel index `i` (any integer near the image) wrapped to [0, n).
uint32_t wrap_index(int64_t i, int64_t n, TextureWrap wrap) {
  switch (wrap) {
    case TextureWrap::repeat:
      i = ((i % n) + n) % n;
      break;
    case TextureWrap::mirror: {
      const int64_t m = ((i % (2 * n)) + 2 * n) % (2 * n);
      i = m < n ? m : 2 * n - 1 - m;
      break;
    }
    case TextureWrap::clamp:
      i = std::clamp<int64_t>(i, 0, n - 1);
      break;
  }
  return static_cast<uint32_t>(i);
}

}  // namespace

ImageTexture::ImageTexture(std::shared_ptr<const TexelImage> image,
                           const ImageTextureOptions& options)
    : image_(std::move(image)), options_(options), map_(options.transform) {
  if (!image_) throw std::invalid_argument("ImageTexture: no image");
}

Vec4 ImageTexture::eval(float u, float v) const {
  const auto [tu, tv] = map_.apply(u, v);
  // Image coordinates: s to the right, t down from the top row.
  const double s = reduce(tu, options_.wrap_u);
  const double t =
      reduce(options_.origin == UvOrigin::bottom_left ? 1.0 - tv : tv, options_.wrap_v);
  const int64_t w = image_->width(), h = image_->height();
  const double x = s * static_cast<double>(w), y = t * static_cast<double>(h);
  if (options_.filter == TextureFilter::nearest) {
    const auto fx = static_cast<int64_t>(std::floor(x)), fy = static_cast<int64_t>(std::floor(y));
    return image_->texel(wrap_index(fx, w, options_.wrap_u), wrap_index(fy, h, options_.wrap_v));
  }
  const double cx = x - 0.5, cy = y - 0.5;  // texel centres sit at half-integers
  const double x0 = std::floor(cx), y0 = std::floor(cy);
  const auto fx = static_cast<float>(cx - x0), fy = static_cast<float>(cy - y0);
  const auto ix = static_cast<int64_t>(x0), iy = static_cast<int64_t>(y0);
  const uint32_t xa = wrap_index(ix, w, options_.wrap_u),
                 xb = wrap_index(ix + 1, w, options_.wrap_u);
  const uint32_t ya = wrap_index(iy, h, options_.wrap_v),
                 yb = wrap_index(iy + 1, h, options_.wrap_v);
  const Vec4 top = (1.f - fx) * image_->texel(xa, ya) + fx * image_->texel(xb, ya);
  const Vec4 bottom = (1.f - fx) * image_->texel(xa, yb) + fx * image_->texel(xb, yb);
  return (1.f - fy) * top + fy * bottom;
}

float ImageTexture::eval_mono(float u, float v) const {
  const Vec4 c = eval(u, v);
  if (image_->channels() <= 2) return c.x;
  return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}

}  // namespace rayfarm
