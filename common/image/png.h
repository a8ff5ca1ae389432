#pragma once
// Tone-mapped 8-bit PNG previews of linear images.
#include <filesystem>

#include "common/image/exr.h"

namespace rayfarm {

/// Writes an sRGB preview (linear values clamped to [0,1] after `exposure` scaling), atomically.
void write_png_preview(const std::filesystem::path& path, const Image& image, float exposure = 1.f);

}  // namespace rayfarm
