#pragma once
// An image texture: a shared TexelImage looked up at (u, v) with a filter, a wrap mode per axis,
// a UV transform and a UV origin. docs/textures.md.
#include <memory>

#include "common/math/vec4.h"
#include "renderer/textures/texel_image.h"
#include "renderer/textures/uv_transform.h"

namespace rayfarm {

/// Read-only after construction: lookups from any number of threads.
class ImageTexture {
 public:
  ImageTexture(std::shared_ptr<const TexelImage> image, const ImageTextureOptions& options);

  /// Linear RGBA at (u, v). Texel (i, j) covers [i, i + 1) x [j, j + 1) of the image scaled to
  /// its size in texels; bilinear interpolates the four nearest texel centres after decoding
  /// each to linear. Non-finite coordinates read as 0.
  Vec4 eval(float u, float v) const;
  /// One channel of eval (0 red, 1 green, 2 blue, 3 alpha).
  float eval_channel(float u, float v, int channel) const { return eval(u, v)[channel]; }
  /// A single value: gray images' value, otherwise the luminance of the linear RGB (Rec. 709
  /// weights, the sRGB primaries).
  float eval_mono(float u, float v) const;

  const TexelImage& image() const { return *image_; }
  const std::shared_ptr<const TexelImage>& shared_image() const { return image_; }
  const ImageTextureOptions& options() const { return options_; }

 private:
  std::shared_ptr<const TexelImage> image_;
  ImageTextureOptions options_;
  UvMap map_;
};

}  // namespace rayfarm
