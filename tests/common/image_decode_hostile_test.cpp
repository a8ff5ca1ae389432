// decode_image on hostile input: every truncation of small valid files, every single-byte
// corruption, and headers that lie about the image's size (refused before any allocation).
#include <zlib.h>

#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/image/decode_image.h"
#include "common/scene/scene_files.h"
#include "tests/support/image_writers.h"

// The largest single allocation made with operator new: a header that lies about its size must
// be refused before the decoder allocates for it. (GCC takes the replaced operators, once
// inlined, for a malloc/delete mismatch.)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
std::atomic<size_t> g_largest_new{0};
}  // namespace

void* operator new(size_t size) {
  size_t seen = g_largest_new.load(std::memory_order_relaxed);
  while (size > seen && !g_largest_new.compare_exchange_weak(seen, size)) {
  }
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }

namespace rayfarm {
namespace {

using testing::Bytes;

/// What decoding `bytes` gives: "ok", or the SceneError's message. Any other exception fails.
std::string outcome(const Bytes& bytes, const std::string& name) {
  try {
    decode_image(std::span<const uint8_t>(bytes.data(), bytes.size()), name);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "ok";
}

/// Small valid files of every format, by name.
std::vector<std::pair<std::string, Bytes>> valid_files() {
  std::vector<std::pair<std::string, Bytes>> files;
  testing::PngSpec rgba;
  rgba.width = 6, rgba.height = 5, rgba.color_type = PNG_COLOR_TYPE_RGB_ALPHA;
  rgba.interlaced = true;
  for (int i = 0; i < 6 * 5 * 4; ++i) rgba.samples.push_back(static_cast<uint16_t>(i * 7 % 256));
  files.emplace_back("rgba.png", testing::encode_png(rgba));
  testing::PngSpec palette;
  palette.width = 5, palette.height = 3, palette.color_type = PNG_COLOR_TYPE_PALETTE;
  palette.bit_depth = 2;
  palette.palette = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {10, 11, 12}};
  palette.palette_alpha = {0, 255};
  for (int i = 0; i < 15; ++i) palette.samples.push_back(static_cast<uint16_t>(i % 4));
  files.emplace_back("palette.png", testing::encode_png(palette));
  Bytes pixels;
  for (int i = 0; i < 9 * 7 * 3; ++i) pixels.push_back(static_cast<uint8_t>(i * 3));
  files.emplace_back("rgb.jpg", testing::encode_jpeg(pixels, 9, 7, 3, 90));
  files.emplace_back("gray.jpg", testing::encode_jpeg(pixels, 9, 7, 1, 90, true));
  std::vector<float> samples;
  for (int i = 0; i < 4 * 3 * 4; ++i) samples.push_back(0.1f * static_cast<float>(i));
  files.emplace_back("half.exr", testing::encode_exr(samples, 4, 3, {"R", "G", "B", "A"}, true));
  files.emplace_back("float.exr", testing::encode_exr(samples, 4, 3, {"R", "G", "B", "A"}, false,
                                                      Imf::NO_COMPRESSION));
  Bytes rgbe;
  for (int i = 0; i < 9 * 2; ++i) rgbe.insert(rgbe.end(), {200, 100, static_cast<uint8_t>(i), 130});
  files.emplace_back("flat.hdr", testing::encode_hdr(rgbe, 9, 2, false));
  files.emplace_back("rle.hdr", testing::encode_hdr(rgbe, 9, 2, true));
  return files;
}

TEST(ImageDecodeHostile, EveryTruncationIsAnErrorNamingTheFile) {
  for (const auto& [name, file] : valid_files()) {
    ASSERT_EQ(outcome(file, name), "ok") << name;
    for (size_t length = 0; length < file.size(); ++length) {
      const std::string result = outcome(Bytes(file.begin(), file.begin() + length), name);
      ASSERT_EQ(result.rfind(name + ": ", 0), 0u)
          << name << " cut to " << length << " of " << file.size() << " bytes: " << result;
    }
  }
}

TEST(ImageDecodeHostile, EverySingleByteCorruptionDecodesOrIsAnError) {
  for (const auto& [name, file] : valid_files()) {
    for (size_t at = 0; at < file.size(); ++at) {
      for (uint8_t flip : {0x01, 0x80, 0xff}) {
        Bytes corrupt = file;
        corrupt[at] ^= flip;
        const std::string result = outcome(corrupt, name);
        ASSERT_TRUE(result == "ok" || result.rfind(name + ": ", 0) == 0)
            << name << " with byte " << at << " ^ " << int{flip} << ": " << result;
      }
    }
  }
}

/// A PNG that stops after its header and the start of its first IDAT chunk.
Bytes png_header_only(uint32_t width, uint32_t height) {
  Bytes file = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  auto be32 = [&](uint32_t v) {
    for (int s = 24; s >= 0; s -= 8) file.push_back(static_cast<uint8_t>(v >> s));
  };
  be32(13);
  const size_t type_at = file.size();
  file.insert(file.end(), {'I', 'H', 'D', 'R'});
  be32(width);
  be32(height);
  file.insert(file.end(), {8, 6, 0, 0, 0});  // 8-bit RGBA
  be32(static_cast<uint32_t>(crc32(0, file.data() + type_at, 17)));
  be32(100);
  file.insert(file.end(), {'I', 'D', 'A', 'T'});
  return file;
}

/// `file` with the 16-bit big-endian words at `at` and `at + 2` set (a JPEG SOF's height, width).
Bytes with_jpeg_size(Bytes file, uint16_t width, uint16_t height) {
  for (size_t i = 0; i + 8 < file.size(); ++i) {
    if (file[i] == 0xff && (file[i + 1] == 0xc0 || file[i + 1] == 0xc2)) {
      file[i + 5] = static_cast<uint8_t>(height >> 8), file[i + 6] = height & 0xff;
      file[i + 7] = static_cast<uint8_t>(width >> 8), file[i + 8] = width & 0xff;
      return file;
    }
  }
  ADD_FAILURE() << "no SOF marker";
  return file;
}

/// `file` with the EXR data window's maximum corner set to (x1, y1).
Bytes with_exr_window(Bytes file, int32_t x1, int32_t y1) {
  const std::string key("dataWindow\0box2i\0", 17);
  const auto it = std::search(file.begin(), file.end(), key.begin(), key.end());
  EXPECT_NE(it, file.end());
  const size_t at = static_cast<size_t>(it - file.begin()) + key.size() + 4 + 8;
  for (int b = 0; b < 4; ++b) {
    file[at + b] = static_cast<uint8_t>(static_cast<uint32_t>(x1) >> (8 * b));
    file[at + 4 + b] = static_cast<uint8_t>(static_cast<uint32_t>(y1) >> (8 * b));
  }
  return file;
}

Bytes hdr_header(const std::string& resolution) {
  const std::string text = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + resolution + "\n";
  Bytes file(text.begin(), text.end());
  file.resize(file.size() + 1024, 0x80);
  return file;
}

TEST(ImageDecodeHostile, LyingHeadersAreRefusedBeforeAllocation) {
  const auto files = valid_files();
  const Bytes jpeg = files[2].second;
  const Bytes exr = files[4].second;
  struct Case {
    std::string name;
    Bytes file;
    std::string says;  ///< in the message
  };
  const std::vector<Case> cases = {
      {"side.png", png_header_only(100000, 4), "100000x4, over the largest side of 16384"},
      {"pixels.png", png_header_only(16384, 16384), "16384x16384, over the limit of 67108864"},
      {"side.jpg", with_jpeg_size(jpeg, 60000, 8), "60000x8, over the largest side of 16384"},
      {"pixels.jpg", with_jpeg_size(jpeg, 16000, 16000), "16000x16000, over the limit"},
      {"side.exr", with_exr_window(exr, 99999, 2), "100000x3, over the largest side"},
      {"pixels.exr", with_exr_window(exr, 9999, 9999), "10000x10000, over the limit"},
      {"negative.exr", with_exr_window(exr, -5, 2), "-4x3"},
      {"side.hdr", hdr_header("-Y 3 +X 100000"), "100000x3, over the largest side"},
      {"pixels.hdr", hdr_header("-Y 16384 +X 16384"), "16384x16384, over the limit"},
      {"digits.hdr", hdr_header("-Y 3 +X 12345678901"), "is not \"-Y height +X width\""},
  };
  for (const Case& c : cases) {
    g_largest_new = 0;
    const std::string result = outcome(c.file, c.name);
    EXPECT_EQ(result.rfind(c.name + ": ", 0), 0u) << result;
    EXPECT_NE(result.find(c.says), std::string::npos) << c.name << ": " << result;
    EXPECT_LT(g_largest_new.load(), size_t{1} << 20) << c.name;
  }
}

/// A valid progressive gray JPEG with 1 + 63 * `passes` scans: the DC, then each AC coefficient
/// on its own, sent `passes` bits at a time by successive approximation (libjpeg accepts such a
/// script; no encoder's default comes near).
Bytes jpeg_with_scans(int passes) {
  constexpr uint32_t kSide = 16;
  Bytes pixels;
  for (uint32_t i = 0; i < kSide * kSide; ++i) pixels.push_back(static_cast<uint8_t>(i * 37));
  std::vector<jpeg_scan_info> script;
  script.push_back({1, {0, 0, 0, 0}, 0, 0, 0, 0});
  for (int k = 1; k <= 63; ++k) {
    for (int p = passes - 1; p >= 0; --p) {
      const int ah = p == passes - 1 ? 0 : p + 1;
      script.push_back({1, {0, 0, 0, 0}, k, k, ah, p});
    }
  }
  jpeg_compress_struct cinfo;
  jpeg_error_mgr errors;
  cinfo.err = jpeg_std_error(&errors);
  jpeg_create_compress(&cinfo);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = cinfo.image_height = kSide;
  cinfo.input_components = 1;
  cinfo.in_color_space = JCS_GRAYSCALE;
  jpeg_set_defaults(&cinfo);
  cinfo.scan_info = script.data();
  cinfo.num_scans = static_cast<int>(script.size());
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < kSide) {
    JSAMPROW row = pixels.data() + size_t{cinfo.next_scanline} * kSide;
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  Bytes out(buffer, buffer + size);
  jpeg_destroy_compress(&cinfo);
  std::free(buffer);
  return out;
}

TEST(ImageDecodeHostile, AProgressiveJpegWithTooManyScansIsRefused) {
  // 1 + 63 * 6 = 379 scans: under the cap of 500, decoded.
  EXPECT_EQ(outcome(jpeg_with_scans(6), "some.jpg"), "ok");
  // 1 + 63 * 9 = 568 scans: each a pass over the whole image, refused before the 501st.
  const std::string refused = outcome(jpeg_with_scans(9), "many.jpg");
  EXPECT_EQ(refused.rfind("many.jpg: ", 0), 0u) << refused;
  EXPECT_NE(refused.find("more than 500 progressive scans"), std::string::npos) << refused;
}

TEST(ImageDecodeHostile, UnknownFormatsAreNamed) {
  EXPECT_EQ(outcome({}, "e.png"),
            "e.png: not a PNG, JPEG, OpenEXR or Radiance HDR image (the file "
            "is empty)");
  EXPECT_EQ(outcome({'G', 'I', 'F', '8', '9', 'a'}, "x.png"),
            "x.png: not a PNG, JPEG, OpenEXR or Radiance HDR image (it starts with the bytes 47 "
            "49 46 38 39 61)");
}

}  // namespace
}  // namespace rayfarm
