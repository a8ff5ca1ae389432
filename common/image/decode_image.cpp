#include "common/image/decode_image.h"

#include <cstdio>
#include <initializer_list>

#include "common/image/image_formats.h"
#include "common/scene/scene_files.h"

namespace rayfarm {

namespace {

bool starts_with(std::span<const uint8_t> bytes, std::initializer_list<uint8_t> magic) {
  if (bytes.size() < magic.size()) return false;
  size_t i = 0;
  for (uint8_t b : magic) {
    if (bytes[i++] != b) return false;
  }
  return true;
}

}  // namespace

DecodedImage decode_image(std::span<const uint8_t> bytes, const std::string& name) {
  using namespace image_formats;
  if (starts_with(bytes, {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'})) {
    return decode_png(bytes, name);
  }
  if (starts_with(bytes, {0xff, 0xd8, 0xff})) return decode_jpeg(bytes, name);
  if (starts_with(bytes, {0x76, 0x2f, 0x31, 0x01})) return decode_exr(bytes, name);
  if (starts_with(bytes, {'#', '?'})) return decode_hdr(bytes, name);
  std::string first;
  for (size_t i = 0; i < bytes.size() && i < 8; ++i) {
    char hex[4];
    std::snprintf(hex, sizeof(hex), "%s%02x", i == 0 ? "" : " ", bytes[i]);
    first += hex;
  }
  throw SceneError(
      name + ": not a PNG, JPEG, OpenEXR or Radiance HDR image (" +
      (bytes.empty() ? std::string("the file is empty") : "it starts with the bytes " + first) +
      ")");
}

}  // namespace rayfarm
