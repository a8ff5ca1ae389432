#pragma once
// Tone-mapped 8-bit PNG previews of linear images.
#include <cstdint>
#include <filesystem>
#include <vector>

#include "common/image/exr.h"

namespace rayfarm {

/// The 8-bit sRGB codes of a linear image, as its preview shows them: each value scaled by
/// `exposure`, clamped to [0, 1] (non-finite values read 0), encoded and rounded.
std::vector<uint8_t> preview_pixels(const Image& image, float exposure = 1.f);

/// Writes an sRGB preview (linear values clamped to [0,1] after `exposure` scaling), atomically.
void write_png_preview(const std::filesystem::path& path, const Image& image, float exposure = 1.f);

/// Writes 8-bit sRGB pixels (`rgb`: width * height * 3 bytes, row-major, top row first) as a PNG,
/// atomically. Throws ImageError naming the path on failure.
void write_png_rgb8(const std::filesystem::path& path, const std::vector<uint8_t>& rgb,
                    uint32_t width, uint32_t height);

}  // namespace rayfarm
