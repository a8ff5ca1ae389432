// libFuzzer target: any bytes as an image file. decode_image() must decode them or throw
// SceneError naming the file, and what it decodes must be a consistent image within the limits.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "common/image/decode_image.h"
#include "common/limits.h"
#include "common/scene/scene_files.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rayfarm;
  try {
    const DecodedImage image = decode_image(std::span<const uint8_t>(data, size), "fuzz.img");
    fuzz::require(image.width >= 1 && image.height >= 1, "empty image decoded");
    fuzz::require(image.width <= kMaxTextureSide && image.height <= kMaxTextureSide,
                  "side over the limit");
    fuzz::require(int64_t{image.width} * image.height <= kMaxTexturePixels,
                  "pixels over the limit");
    fuzz::require(image.channels >= 1 && image.channels <= 4, "channel count out of range");
    const size_t samples = size_t{image.width} * image.height * image.channels;
    fuzz::require(image.bytes.empty() != image.floats.empty(), "not exactly one sample kind");
    fuzz::require(image.bytes.size() + image.floats.size() == samples, "sample count mismatch");
  } catch (const SceneError& e) {
    fuzz::require(std::string(e.what()).rfind("fuzz.img: ", 0) == 0, "error does not name file");
  }
  return 0;
}
