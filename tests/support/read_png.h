#pragma once
// Test helper: reads a PNG file back as 8-bit RGB with libpng's simplified API.
#include <png.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace rayfarm::testing {

/// An 8-bit RGB image read from a file; empty (0 x 0) when it could not be read.
struct RgbImage {
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<uint8_t> rgb;  ///< row-major, top row first
  std::string error;         ///< libpng's message when reading failed
};

/// Reads `path` as 8-bit RGB.
inline RgbImage read_png_rgb8(const std::filesystem::path& path) {
  RgbImage result;
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    result.error = image.message;
    return result;
  }
  image.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> pixels(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr)) {
    result.error = image.message;
    return result;
  }
  result.width = image.width;
  result.height = image.height;
  result.rgb = std::move(pixels);
  return result;
}

}  // namespace rayfarm::testing
