// decode_image: each format on small files written here, in every layout the decoders promise,
// and refused input (truncated at every length, lying headers, unsupported variants).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/image/decode_image.h"
#include "common/limits.h"
#include "common/scene/scene_files.h"
#include "tests/support/image_writers.h"

namespace rayfarm {
namespace {

using testing::Bytes;

DecodedImage decode(const Bytes& bytes, const std::string& name = "tex/image") {
  return decode_image(std::span<const uint8_t>(bytes.data(), bytes.size()), name);
}

/// The message of the SceneError that decoding `bytes` throws ("" when it does not throw).
std::string error_of(const Bytes& bytes, const std::string& name = "tex/image") {
  try {
    decode(bytes, name);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

/// Deterministic test samples.
struct Lcg {
  uint32_t state;
  uint32_t next(uint32_t bound) {
    state = state * 1664525u + 1013904223u;
    return (state >> 8) % bound;
  }
};

// ---- PNG ----------------------------------------------------------------------------------------

struct PngCase {
  int color_type;
  int bit_depth;
};

/// A PNG spec with random samples; palette images get a palette of 2^depth colours.
testing::PngSpec random_png(PngCase c, bool interlaced, uint32_t seed) {
  testing::PngSpec spec;
  spec.width = 11;  // odd sizes cover partial bytes and Adam7's uneven passes
  spec.height = 7;
  spec.color_type = c.color_type;
  spec.bit_depth = c.bit_depth;
  spec.interlaced = interlaced;
  Lcg lcg{seed};
  const uint32_t bound = 1u << c.bit_depth;
  for (size_t i = 0; i < size_t{spec.width} * spec.height * testing::png_channels_of(c.color_type);
       ++i) {
    spec.samples.push_back(static_cast<uint16_t>(lcg.next(bound)));
  }
  if (c.color_type == PNG_COLOR_TYPE_PALETTE) {
    for (uint32_t i = 0; i < bound; ++i) {
      spec.palette.push_back({static_cast<png_byte>(lcg.next(256)),
                              static_cast<png_byte>(lcg.next(256)),
                              static_cast<png_byte>(lcg.next(256))});
    }
  }
  return spec;
}

/// A sample of `depth` bits widened to 8 bits, as libpng does (bit replication: 1 -> 255).
int widen(uint16_t v, int depth) { return depth == 8 ? v : v * 255 / ((1 << depth) - 1); }

TEST(PngDecode, EveryColourTypeAndBitDepthInterlacedOrNot) {
  const std::vector<PngCase> cases = {
      {PNG_COLOR_TYPE_GRAY, 1},        {PNG_COLOR_TYPE_GRAY, 2},
      {PNG_COLOR_TYPE_GRAY, 4},        {PNG_COLOR_TYPE_GRAY, 8},
      {PNG_COLOR_TYPE_GRAY, 16},       {PNG_COLOR_TYPE_GRAY_ALPHA, 8},
      {PNG_COLOR_TYPE_GRAY_ALPHA, 16}, {PNG_COLOR_TYPE_RGB, 8},
      {PNG_COLOR_TYPE_RGB, 16},        {PNG_COLOR_TYPE_RGB_ALPHA, 8},
      {PNG_COLOR_TYPE_RGB_ALPHA, 16},  {PNG_COLOR_TYPE_PALETTE, 1},
      {PNG_COLOR_TYPE_PALETTE, 2},     {PNG_COLOR_TYPE_PALETTE, 4},
      {PNG_COLOR_TYPE_PALETTE, 8}};
  uint32_t seed = 1;
  for (const PngCase& c : cases) {
    for (bool interlaced : {false, true}) {
      SCOPED_TRACE("colour type " + std::to_string(c.color_type) + ", depth " +
                   std::to_string(c.bit_depth) + (interlaced ? ", interlaced" : ""));
      const testing::PngSpec spec = random_png(c, interlaced, seed++);
      const DecodedImage image = decode(testing::encode_png(spec), "t.png");
      const bool palette = c.color_type == PNG_COLOR_TYPE_PALETTE;
      const int channels = palette ? 3 : testing::png_channels_of(c.color_type);
      ASSERT_EQ(image.width, spec.width);
      ASSERT_EQ(image.height, spec.height);
      ASSERT_EQ(image.channels, static_cast<uint32_t>(channels));
      EXPECT_TRUE(image.display_encoded);
      EXPECT_STREQ(image.format, "PNG");
      const size_t pixels = size_t{spec.width} * spec.height;
      if (c.bit_depth == 16) {
        ASSERT_TRUE(image.is_float());
        ASSERT_EQ(image.floats.size(), pixels * channels);
        for (size_t i = 0; i < image.floats.size(); ++i) {
          ASSERT_FLOAT_EQ(image.floats[i], spec.samples[i] / 65535.f) << "sample " << i;
        }
        continue;
      }
      ASSERT_FALSE(image.is_float());
      ASSERT_EQ(image.bytes.size(), pixels * channels);
      for (size_t p = 0; p < pixels; ++p) {
        for (int k = 0; k < channels; ++k) {
          const int want = palette ? (&spec.palette[spec.samples[p]].red)[k]
                                   : widen(spec.samples[p * channels + k], c.bit_depth);
          ASSERT_EQ(image.bytes[p * channels + k], want) << "pixel " << p << " channel " << k;
        }
      }
    }
  }
}

TEST(PngDecode, PaletteTransparencyBecomesAlpha) {
  testing::PngSpec spec = random_png({PNG_COLOR_TYPE_PALETTE, 4}, true, 99);
  spec.palette_alpha = {0, 128, 255, 7};  // entries 4..15 have no tRNS entry: opaque
  const DecodedImage image = decode(testing::encode_png(spec));
  ASSERT_EQ(image.channels, 4u);
  for (size_t p = 0; p < size_t{spec.width} * spec.height; ++p) {
    const uint16_t index = spec.samples[p];
    const int alpha = index < spec.palette_alpha.size() ? spec.palette_alpha[index] : 255;
    EXPECT_EQ(image.bytes[4 * p + 0], spec.palette[index].red);
    EXPECT_EQ(image.bytes[4 * p + 2], spec.palette[index].blue);
    EXPECT_EQ(image.bytes[4 * p + 3], alpha) << "pixel " << p;
  }
}

TEST(PngDecode, TransparentColourBecomesAlpha) {
  // Gray: the one transparent level gets alpha 0, every other level 255.
  testing::PngSpec gray = random_png({PNG_COLOR_TYPE_GRAY, 2}, false, 5);
  gray.has_transparent_colour = true;
  gray.transparent_colour.gray = 1;
  DecodedImage image = decode(testing::encode_png(gray));
  ASSERT_EQ(image.channels, 2u);
  for (size_t p = 0; p < gray.samples.size(); ++p) {
    EXPECT_EQ(image.bytes[2 * p], widen(gray.samples[p], 2));
    EXPECT_EQ(image.bytes[2 * p + 1], gray.samples[p] == 1 ? 0 : 255);
  }
  // RGB: the same with a colour.
  testing::PngSpec rgb = random_png({PNG_COLOR_TYPE_RGB, 8}, false, 6);
  rgb.samples[3] = 10, rgb.samples[4] = 20, rgb.samples[5] = 30;  // pixel 1 is transparent
  rgb.has_transparent_colour = true;
  rgb.transparent_colour.red = 10, rgb.transparent_colour.green = 20;
  rgb.transparent_colour.blue = 30;
  image = decode(testing::encode_png(rgb));
  ASSERT_EQ(image.channels, 4u);
  EXPECT_EQ(image.bytes[4 * 1 + 3], 0);
  EXPECT_EQ(image.bytes[4 * 1 + 0], 10);
  EXPECT_EQ(image.bytes[4 * 0 + 3],
            rgb.samples[0] == 10 && rgb.samples[1] == 20 && rgb.samples[2] == 30 ? 0 : 255);
}

TEST(PngDecode, GammaOneWithoutSrgbChunkIsLinear) {
  testing::PngSpec spec = random_png({PNG_COLOR_TYPE_RGB, 8}, false, 7);
  EXPECT_TRUE(decode(testing::encode_png(spec)).display_encoded);  // no chunk: sRGB
  spec.gamma = 1.0;
  EXPECT_FALSE(decode(testing::encode_png(spec)).display_encoded);
  spec.gamma = 1 / 2.2;
  EXPECT_TRUE(decode(testing::encode_png(spec)).display_encoded);
  spec.gamma = 0;  // an sRGB chunk alone (libpng writes no sRGB chunk beside a gAMA of 1)
  spec.srgb_chunk = true;
  EXPECT_TRUE(decode(testing::encode_png(spec)).display_encoded);
}

// ---- JPEG ---------------------------------------------------------------------------------------

/// A smooth test picture (JPEG's error on it is small), 8-bit, `channels` per pixel.
Bytes gradient(uint32_t width, uint32_t height, int channels) {
  Bytes pixels;
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        pixels.push_back(static_cast<uint8_t>(20 + 6 * x + 4 * y + 30 * c));
      }
    }
  }
  return pixels;
}

/// Decodes with libjpeg's defaults, the reference the decoder must equal.
Bytes plain_libjpeg_decode(const Bytes& file, int channels) {
  jpeg_decompress_struct cinfo;
  jpeg_error_mgr errors;
  cinfo.err = jpeg_std_error(&errors);
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, file.data(), static_cast<unsigned long>(file.size()));
  jpeg_read_header(&cinfo, TRUE);
  cinfo.out_color_space = channels == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_start_decompress(&cinfo);
  Bytes out(size_t{cinfo.output_width} * cinfo.output_height * channels);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = out.data() + size_t{cinfo.output_scanline} * cinfo.output_width * channels;
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return out;
}

TEST(JpegDecode, RgbAndGrayBaselineAndProgressive) {
  for (int channels : {1, 3}) {
    for (bool progressive : {false, true}) {
      SCOPED_TRACE(std::to_string(channels) + " channels" + (progressive ? ", progressive" : ""));
      const uint32_t width = 21, height = 13;
      const Bytes source = gradient(width, height, channels);
      const Bytes file = testing::encode_jpeg(source, width, height, channels, 95, progressive);
      const DecodedImage image = decode(file, "t.jpg");
      ASSERT_EQ(image.width, width);
      ASSERT_EQ(image.height, height);
      ASSERT_EQ(image.channels, static_cast<uint32_t>(channels));
      EXPECT_TRUE(image.display_encoded);
      EXPECT_STREQ(image.format, "JPEG");
      EXPECT_EQ(image.bytes, plain_libjpeg_decode(file, channels));
      // Quality 95 on a smooth gradient: a few levels of error at most (chroma subsampling of
      // the colour picture included).
      double sum = 0;
      int worst = 0;
      for (size_t i = 0; i < source.size(); ++i) {
        const int error = std::abs(int{image.bytes[i]} - int{source[i]});
        worst = std::max(worst, error);
        sum += error;
      }
      EXPECT_LE(worst, 8);
      EXPECT_LE(sum / static_cast<double>(source.size()), 2.0);
    }
  }
}

// ---- OpenEXR ------------------------------------------------------------------------------------

TEST(ExrDecode, FloatAndHalfRgbaRgbAndLuminance) {
  const uint32_t width = 5, height = 3;
  struct Case {
    std::vector<std::string> names;
    bool as_half;
  };
  for (const Case& c : {Case{{"R", "G", "B", "A"}, false}, Case{{"R", "G", "B", "A"}, true},
                        Case{{"R", "G", "B"}, true}, Case{{"Y"}, false}, Case{{"Y", "A"}, true}}) {
    SCOPED_TRACE(std::to_string(c.names.size()) + " channels" + (c.as_half ? ", half" : ""));
    std::vector<float> samples;
    for (size_t i = 0; i < size_t{width} * height * c.names.size(); ++i) {
      samples.push_back(0.001f * static_cast<float>(i * i) + (i % 3 == 0 ? 1000.f : 0.25f));
    }
    const DecodedImage image =
        decode(testing::encode_exr(samples, width, height, c.names, c.as_half), "t.exr");
    ASSERT_EQ(image.width, width);
    ASSERT_EQ(image.height, height);
    ASSERT_EQ(image.channels, c.names.size());
    EXPECT_FALSE(image.display_encoded);
    ASSERT_EQ(image.floats.size(), samples.size());
    for (size_t i = 0; i < samples.size(); ++i) {
      const float want = c.as_half ? static_cast<float>(half(samples[i])) : samples[i];
      ASSERT_EQ(image.floats[i], want) << "sample " << i;
    }
  }
}

TEST(ExrDecode, RefusesFilesWithoutColourChannels) {
  const Bytes file = testing::encode_exr({1, 2, 3, 4}, 2, 2, {"Z"}, false);
  EXPECT_NE(error_of(file, "depth.exr").find("depth.exr: OpenEXR: no R, G, B channels"),
            std::string::npos)
      << error_of(file, "depth.exr");
}

// ---- Radiance HDR -------------------------------------------------------------------------------

/// Pixels over a wide range, with runs (for the run-length form) and black.
std::vector<float> hdr_colours(uint32_t width, uint32_t height) {
  std::vector<float> rgb;
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      const float base = x < 4 ? 1000.f : std::ldexp(1.f, static_cast<int>(x) - 12);
      rgb.insert(rgb.end(), {base, base * 0.5f, y == 1 ? 0.f : base * 0.01f});
    }
  }
  rgb[0] = rgb[1] = rgb[2] = 0.f;
  return rgb;
}

TEST(HdrDecode, FlatAndRunLengthScanlinesGiveRadiancesValues) {
  const uint32_t width = 20, height = 3;
  const std::vector<float> colours = hdr_colours(width, height);
  Bytes rgbe(size_t{width} * height * 4);
  for (size_t p = 0; p < size_t{width} * height; ++p) {
    testing::float_to_rgbe(&colours[3 * p], &rgbe[4 * p]);
  }
  for (bool rle : {false, true}) {
    SCOPED_TRACE(rle ? "run-length" : "flat");
    const Bytes file = testing::encode_hdr(rgbe, width, height, rle);
    const DecodedImage image = decode(file, "t.hdr");
    ASSERT_EQ(image.width, width);
    ASSERT_EQ(image.height, height);
    ASSERT_EQ(image.channels, 3u);
    EXPECT_FALSE(image.display_encoded);
    for (size_t p = 0; p < size_t{width} * height; ++p) {
      for (int c = 0; c < 3; ++c) {
        const uint8_t* e = &rgbe[4 * p];
        // Radiance's definition: (mantissa + 0.5) * 2^(exponent - 136), 0 for exponent 0.
        const float want = e[3] == 0 ? 0.f : (e[c] + 0.5f) * std::ldexp(1.f, e[3] - 136);
        ASSERT_EQ(image.floats[3 * p + c], want) << "pixel " << p << " channel " << c;
        // Within the format's precision of the colour written: the shared exponent leaves 8
        // bits to the largest component.
        const float largest = std::max({colours[3 * p], colours[3 * p + 1], colours[3 * p + 2]});
        EXPECT_NEAR(image.floats[3 * p + c], colours[3 * p + c], largest / 128.f + 1e-30f);
      }
    }
  }
  // The exponent matters: 1000 is stored with exponent 138 (1000 = 0.98 * 2^10).
  EXPECT_EQ(rgbe[4 * 1 + 3], 138);
  EXPECT_NEAR(decode(testing::encode_hdr(rgbe, width, height, true)).floats[3], 1000.f, 4.f);
}

TEST(HdrDecode, OldRunLengthRepeatsThePreviousPixel) {
  const std::string header = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 5\n";
  Bytes file(header.begin(), header.end());
  file.insert(file.end(), {128, 64, 32, 129, 1, 1, 1, 3, 10, 20, 30, 128});  // pixel, repeat 3
  const DecodedImage image = decode(file);
  ASSERT_EQ(image.floats.size(), 15u);
  for (int x = 0; x < 4; ++x) EXPECT_EQ(image.floats[3 * x], 128.5f / 128.f);
  EXPECT_EQ(image.floats[3 * 4 + 2], 30.5f / 256.f);
}

TEST(HdrDecode, RefusesOtherOrientationsAndFormats) {
  auto with_header = [](const std::string& text) {
    Bytes file(text.begin(), text.end());
    file.resize(file.size() + 64, 0);
    return file;
  };
  EXPECT_NE(error_of(with_header("#?RADIANCE\n\n+Y 2 +X 2\n"), "a.hdr")
                .find("a.hdr: Radiance HDR: the resolution line \"+Y 2 +X 2\" is not"),
            std::string::npos);
  EXPECT_NE(error_of(with_header("#?RADIANCE\n\n-Y 2 -X 2\n")).find("orientations"),
            std::string::npos);
  EXPECT_NE(error_of(with_header("#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 2 +X 2\n"))
                .find("unsupported FORMAT=32-bit_rle_xyze"),
            std::string::npos);
}

}  // namespace
}  // namespace rayfarm
