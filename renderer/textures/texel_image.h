#pragma once
// A decoded image as textures read it: 8-bit samples stay 8-bit (decoded through a 256-entry
// table at lookup), float samples stay float; every texel comes back as linear RGBA.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/image/decoded_image.h"
#include "common/image/texture_options.h"
#include "common/math/vec4.h"

namespace rayfarm {

/// The sRGB transfer curve, decoded: display value -> linear (IEC 61966-2-1).
float srgb_to_linear(float encoded);

/// Immutable after construction, so concurrent lookups need no locking.
class TexelImage {
 public:
  /// Takes the samples of `image` (which must hold width * height * channels of them, 1 to 4
  /// channels; std::invalid_argument otherwise).
  TexelImage(DecodedImage&& image, ColourSpace space);

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  uint32_t channels() const { return channels_; }
  /// Whether the colour samples are decoded from sRGB.
  bool srgb() const { return srgb_; }
  /// Bytes held by the samples.
  size_t memory_bytes() const { return bytes_.size() + floats_.size() * sizeof(float); }

  /// The texel at column x, row y (row 0 is the image's top row) as linear RGBA: gray is
  /// (g, g, g, 1), gray + alpha (g, g, g, a), RGB (r, g, b, 1). x < width, y < height.
  Vec4 texel(uint32_t x, uint32_t y) const;

 private:
  uint32_t width_, height_, channels_;
  bool srgb_;
  std::vector<uint8_t> bytes_;
  std::vector<float> floats_;
  const float* colour_table_;  ///< 8-bit colour sample -> linear value
};

}  // namespace rayfarm
