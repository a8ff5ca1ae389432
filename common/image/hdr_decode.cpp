// Radiance HDR (RGBE, .hdr / .pic): a text header, a resolution line, then scanlines that are
// flat RGBE pixels (with the old run-length repeats) or the newer per-channel run-length form.
#include <cmath>
#include <string>
#include <string_view>

#include "common/image/image_formats.h"

namespace rayfarm::image_formats {
namespace {

constexpr const char* kFormat = "Radiance HDR";
/// A header longer than this is not an image header.
constexpr size_t kMaxHeaderBytes = 64 << 10;

/// One RGBE pixel to linear floats, as Radiance itself does: the mantissa byte stands for the
/// middle of its interval (m + 0.5), scaled by 2^(e - 136); exponent 0 is black.
void rgbe_to_float(const uint8_t* rgbe, float* out) {
  if (rgbe[3] == 0) {
    out[0] = out[1] = out[2] = 0.f;
    return;
  }
  const float scale = std::ldexp(1.f, int{rgbe[3]} - 136);
  for (int c = 0; c < 3; ++c) out[c] = (static_cast<float>(rgbe[c]) + 0.5f) * scale;
}

/// Reads the decimal number at `text`[at...], at most 9 digits; -1 when there is none.
int64_t read_number(std::string_view text, size_t& at) {
  int64_t value = 0;
  size_t digits = 0;
  while (at < text.size() && text[at] >= '0' && text[at] <= '9' && digits < 9) {
    value = value * 10 + (text[at++] - '0');
    ++digits;
  }
  return digits == 0 || (at < text.size() && text[at] >= '0' && text[at] <= '9') ? -1 : value;
}

class HdrReader {
 public:
  HdrReader(std::span<const uint8_t> bytes, const std::string& name)
      : bytes_(bytes),
        text_(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
        name_(name) {}

  DecodedImage read() {
    read_header();
    const auto [width, height] = read_resolution();
    check_size(name_, kFormat, width, height);
    DecodedImage image;
    image.width = static_cast<uint32_t>(width);
    image.height = static_cast<uint32_t>(height);
    image.channels = 3;
    image.format = kFormat;
    image.floats.resize(size_t{image.width} * image.height * 3);
    std::vector<uint8_t> scanline(size_t{image.width} * 4);
    for (uint32_t y = 0; y < image.height; ++y) {
      read_scanline(scanline, y);
      float* row = image.floats.data() + size_t{y} * image.width * 3;
      for (uint32_t x = 0; x < image.width; ++x) rgbe_to_float(&scanline[4 * x], row + 3 * x);
    }
    return image;
  }

 private:
  [[noreturn]] void fail_at(const std::string& what) const {
    fail(name_, kFormat,
         what + ", at byte " + std::to_string(at_) + " of " + std::to_string(bytes_.size()));
  }

  /// The header's lines up to the empty line that ends it: "#?PROGRAM" first, FORMAT= checked,
  /// the others (EXPOSURE, GAMMA, PRIMARIES, comments) ignored.
  void read_header() {
    bool first = true;
    for (;;) {
      const size_t end = text_.find('\n', at_);
      if (end == std::string_view::npos || end > kMaxHeaderBytes) {
        fail_at("the header does not end (no empty line within " + std::to_string(kMaxHeaderBytes) +
                " bytes)");
      }
      const std::string_view line = text_.substr(at_, end - at_);
      if (first && line.substr(0, 2) != "#?") fail_at("the first line is not #?RADIANCE");
      if (!first && line.empty()) {
        at_ = end + 1;
        return;
      }
      if (line.substr(0, 7) == "FORMAT=" && line != "FORMAT=32-bit_rle_rgbe") {
        fail_at("unsupported " + std::string(line) + " (only 32-bit_rle_rgbe is read)");
      }
      first = false;
      at_ = end + 1;
    }
  }

  /// "-Y H +X W": rows from the top, pixels from the left. Other orientations are refused.
  std::pair<int64_t, int64_t> read_resolution() {
    const size_t end = text_.find('\n', at_);
    if (end == std::string_view::npos || end - at_ > 64) fail_at("no resolution line");
    const std::string_view line = text_.substr(at_, end - at_);
    size_t at = 3;
    int64_t height = -1, width = -1;
    if (line.substr(0, 3) == "-Y ") {
      height = read_number(line, at);
      if (line.substr(at, 4) == " +X ") {
        at += 4;
        width = read_number(line, at);
      }
    }
    if (height < 0 || width < 0 || at != line.size()) {
      fail_at("the resolution line \"" + std::string(line.substr(0, 32)) +
              "\" is not \"-Y height +X width\" (other orientations are not supported)");
    }
    at_ = end + 1;
    return {width, height};
  }

  void need(size_t count, uint32_t y) const {
    if (bytes_.size() - at_ < count) {
      fail_at("the file ends early, in scanline " + std::to_string(y));
    }
  }

  void read_scanline(std::vector<uint8_t>& out, uint32_t y) {
    const size_t width = out.size() / 4;
    const bool rle = width >= 8 && width < 0x8000 && bytes_.size() - at_ >= 4 && bytes_[at_] == 2 &&
                     bytes_[at_ + 1] == 2 && (bytes_[at_ + 2] & 0x80) == 0;
    if (rle) {
      read_rle_scanline(out, y);
    } else {
      read_flat_scanline(out, y);
    }
  }

  /// The newer form: 2, 2, width (16 bits), then each channel run-length coded in turn.
  void read_rle_scanline(std::vector<uint8_t>& out, uint32_t y) {
    const size_t width = out.size() / 4;
    const size_t stated = (size_t{bytes_[at_ + 2]} << 8) | bytes_[at_ + 3];
    if (stated != width) {
      fail_at("scanline " + std::to_string(y) + " says it is " + std::to_string(stated) +
              " pixels wide, the image is " + std::to_string(width));
    }
    at_ += 4;
    for (size_t c = 0; c < 4; ++c) {
      size_t x = 0;
      while (x < width) {
        need(1, y);
        const size_t code = bytes_[at_++];
        const bool run = code > 128;
        const size_t count = run ? code - 128 : code;
        if (count == 0 || count > width - x) {
          fail_at("a run of " + std::to_string(count) + " in scanline " + std::to_string(y) +
                  " does not fit the " + std::to_string(width - x) + " pixels left");
        }
        need(run ? 1 : count, y);
        for (size_t i = 0; i < count; ++i) out[4 * (x + i) + c] = bytes_[run ? at_ : at_ + i];
        at_ += run ? 1 : count;
        x += count;
      }
    }
  }

  /// Flat RGBE pixels; a pixel 1, 1, 1, n repeats the previous one n times (n << 8 after
  /// another such pixel, and so on: the original Radiance run-length form).
  void read_flat_scanline(std::vector<uint8_t>& out, uint32_t y) {
    const size_t width = out.size() / 4;
    size_t x = 0;
    int shift = 0;
    while (x < width) {
      need(4, y);
      const uint8_t* p = bytes_.data() + at_;
      at_ += 4;
      if (p[0] == 1 && p[1] == 1 && p[2] == 1) {
        if (x == 0 || shift > 16)
          fail_at("a repeat with nothing to repeat, in scanline " + std::to_string(y));
        const size_t count = size_t{p[3]} << shift;
        if (count > width - x) {
          fail_at("a repeat of " + std::to_string(count) + " in scanline " + std::to_string(y) +
                  " does not fit the " + std::to_string(width - x) + " pixels left");
        }
        for (size_t i = 0; i < count; ++i, ++x) {
          for (int c = 0; c < 4; ++c) out[4 * x + c] = out[4 * (x - 1) + c];
        }
        shift += 8;
      } else {
        for (int c = 0; c < 4; ++c) out[4 * x + c] = p[c];
        ++x;
        shift = 0;
      }
    }
  }

  std::span<const uint8_t> bytes_;
  std::string_view text_;
  const std::string& name_;
  size_t at_ = 0;
};

}  // namespace

DecodedImage decode_hdr(std::span<const uint8_t> bytes, const std::string& name) {
  return HdrReader(bytes, name).read();
}

}  // namespace rayfarm::image_formats
