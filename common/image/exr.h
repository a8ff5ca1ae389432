#pragma once
// OpenEXR input and output of float32 RGB images (plus optional extra float channels).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayfarm {

/// A file that cannot be read or written; the message names the file and the cause.
class ImageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A float32 image: interleaved RGB, row-major, top row first, plus named extra channels.
struct Image {
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<float> rgb;                                  ///< 3 * width * height
  std::map<std::string, std::vector<float>> extra;         ///< channel name -> width * height
  std::map<std::string, std::string> attributes;           ///< string header attributes
};

/// Writes a float32 EXR (ZIP compression) to a temporary file beside `path`, then renames it.
void write_exr(const std::filesystem::path& path, const Image& image);
/// What a reader expects of an EXR, checked from its header before any pixel is allocated.
struct ExrExpect {
  uint32_t width = 0, height = 0;  ///< the image's size; 0 x 0 = any size
  bool rgb_only = false;           ///< other channels are not read (nor allocated)
};

/// Reads an EXR's R, G, B channels (and any others into `extra`) as float32. Throws ImageError.
Image read_exr(const std::filesystem::path& path, const ExrExpect& expect = {});

}  // namespace rayfarm
