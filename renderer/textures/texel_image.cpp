#include "renderer/textures/texel_image.h"

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rayfarm {
namespace {

std::array<float, 256> make_table(bool srgb) {
  std::array<float, 256> table{};
  for (int i = 0; i < 256; ++i) {
    const float v = static_cast<float>(i) / 255.f;
    table[static_cast<size_t>(i)] = srgb ? srgb_to_linear(v) : v;
  }
  return table;
}

const std::array<float, 256> kSrgbTable = make_table(true);
const std::array<float, 256> kLinearTable = make_table(false);

}  // namespace

float srgb_to_linear(float encoded) {
  const double v = encoded;
  return static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
}

TexelImage::TexelImage(DecodedImage&& image, ColourSpace space)
    : width_(image.width),
      height_(image.height),
      channels_(image.channels),
      srgb_(space == ColourSpace::srgb ||
            (space == ColourSpace::from_file && image.display_encoded)),
      bytes_(std::move(image.bytes)),
      floats_(std::move(image.floats)),
      colour_table_(srgb_ ? kSrgbTable.data() : kLinearTable.data()) {
  const size_t samples = size_t{width_} * height_ * channels_;
  const bool one_kind = bytes_.empty() != floats_.empty();
  if (width_ == 0 || height_ == 0 || channels_ < 1 || channels_ > 4 || !one_kind ||
      (bytes_.size() + floats_.size()) != samples) {
    throw std::invalid_argument("TexelImage: inconsistent image (" + std::to_string(width_) + "x" +
                                std::to_string(height_) + ", " + std::to_string(channels_) +
                                " channels)");
  }
}

Vec4 TexelImage::texel(uint32_t x, uint32_t y) const {
  const size_t at = (size_t{y} * width_ + x) * channels_;
  float s[4];
  if (!bytes_.empty()) {
    const uint8_t* p = bytes_.data() + at;
    const bool has_alpha = channels_ == 2 || channels_ == 4;
    for (uint32_t c = 0; c < channels_; ++c) {
      const bool alpha = has_alpha && c == channels_ - 1;
      s[c] = alpha ? kLinearTable[p[c]] : colour_table_[p[c]];
    }
  } else {
    const float* p = floats_.data() + at;
    const bool has_alpha = channels_ == 2 || channels_ == 4;
    for (uint32_t c = 0; c < channels_; ++c) {
      const bool alpha = has_alpha && c == channels_ - 1;
      s[c] = srgb_ && !alpha ? srgb_to_linear(p[c]) : p[c];
    }
  }
  switch (channels_) {
    case 1:
      return {s[0], s[0], s[0], 1.f};
    case 2:
      return {s[0], s[0], s[0], s[1]};
    case 3:
      return {s[0], s[1], s[2], 1.f};
    default:
      return {s[0], s[1], s[2], s[3]};
  }
}

}  // namespace rayfarm
