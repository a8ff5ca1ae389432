#pragma once
// What the image decoders (decode_image.h) return.
#include <cstdint>
#include <vector>

namespace rayfarm {

/// A decoded image: interleaved samples, row-major, top row first. Exactly one of `bytes` and
/// `floats` holds the samples (width * height * channels of them).
struct DecodedImage {
  uint32_t width = 0;
  uint32_t height = 0;
  /// 1: gray, 2: gray + alpha, 3: RGB, 4: RGBA.
  uint32_t channels = 0;
  /// 8-bit samples (8-bit PNG, JPEG; PNG of 1, 2 or 4 bits widened to 8).
  std::vector<uint8_t> bytes;
  /// Float samples: OpenEXR and Radiance HDR as stored; 16-bit PNG as value / 65535, so that the
  /// file's precision survives (8 bits would band smooth gradients and height maps).
  std::vector<float> floats;
  /// Whether the colour samples are display-encoded (sRGB transfer curve) rather than linear.
  /// Alpha is always linear. PNG and JPEG: true, except a PNG whose gAMA chunk says 1.0 and that
  /// has no sRGB chunk. OpenEXR and Radiance HDR: false.
  bool display_encoded = false;
  /// "PNG", "JPEG", "OpenEXR" or "Radiance HDR", for messages.
  const char* format = "";

  bool is_float() const { return !floats.empty(); }
};

}  // namespace rayfarm
