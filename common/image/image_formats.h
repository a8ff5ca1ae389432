#pragma once
// The per-format decoders behind decode_image() (decode_image.h), and what they share. Each one
// takes the whole file and the name used in messages, and throws SceneError.
#include <cstdint>
#include <span>
#include <string>

#include "common/image/decoded_image.h"

namespace rayfarm::image_formats {

DecodedImage decode_png(std::span<const uint8_t> bytes, const std::string& name);
DecodedImage decode_jpeg(std::span<const uint8_t> bytes, const std::string& name);
DecodedImage decode_exr(std::span<const uint8_t> bytes, const std::string& name);
DecodedImage decode_hdr(std::span<const uint8_t> bytes, const std::string& name);

/// Throws SceneError "NAME: FORMAT: WHAT".
[[noreturn]] void fail(const std::string& name, const char* format, const std::string& what);

/// Throws unless width x height (from a header) is a non-empty image within kMaxTextureSide and
/// kMaxTexturePixels; called before anything of that size is allocated.
void check_size(const std::string& name, const char* format, int64_t width, int64_t height);

}  // namespace rayfarm::image_formats
