#include "common/image/image_formats.h"

#include "common/limits.h"
#include "common/scene/scene_files.h"

namespace rayfarm {
namespace image_formats {

void fail(const std::string& name, const char* format, const std::string& what) {
  throw SceneError(name + ": " + format + ": " + what);
}

void check_size(const std::string& name, const char* format, int64_t width, int64_t height) {
  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  if (width <= 0 || height <= 0) fail(name, format, "the header says the image is " + size);
  if (width > kMaxTextureSide || height > kMaxTextureSide) {
    fail(name, format,
         "the header says the image is " + size + ", over the largest side of " +
             std::to_string(kMaxTextureSide) + " pixels");
  }
  if (width * height > kMaxTexturePixels) {
    fail(name, format,
         "the header says the image is " + size + ", over the limit of " +
             std::to_string(kMaxTexturePixels) + " pixels");
  }
}

}  // namespace image_formats

}  // namespace rayfarm
