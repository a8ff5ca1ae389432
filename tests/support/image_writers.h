#pragma once
// Small image files written in memory for the decoder tests and the fuzz seeds: PNG (libpng, any
// colour type, bit depth, palette, tRNS, interlacing, gAMA/sRGB chunks), JPEG (libjpeg), OpenEXR
// (half or float; RGB, RGBA or Y) and Radiance HDR (flat or run-length scanlines).
#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>
// jpeglib.h needs FILE and size_t declared before it.
#include <jpeglib.h>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfOutputFile.h>
#include <half.h>

namespace rayfarm::testing {

using Bytes = std::vector<uint8_t>;

// ---- PNG ----------------------------------------------------------------------------------------

struct PngSpec {
  uint32_t width = 0, height = 0;
  int color_type = PNG_COLOR_TYPE_RGB;
  int bit_depth = 8;
  bool interlaced = false;
  /// Samples as stored: one value per channel (palette index for palette images), row-major.
  std::vector<uint16_t> samples;
  std::vector<png_color> palette;
  /// tRNS: alpha per palette entry, or (for gray / RGB) the one transparent colour.
  std::vector<uint8_t> palette_alpha;
  bool has_transparent_colour = false;
  png_color_16 transparent_colour{};
  double gamma = 0;  ///< a gAMA chunk when > 0
  bool srgb_chunk = false;
};

inline int png_channels_of(int color_type) {
  switch (color_type) {
    case PNG_COLOR_TYPE_GRAY:
      return 1;
    case PNG_COLOR_TYPE_GRAY_ALPHA:
      return 2;
    case PNG_COLOR_TYPE_RGB:
      return 3;
    case PNG_COLOR_TYPE_RGB_ALPHA:
      return 4;
    default:
      return 1;  // palette
  }
}

inline void png_write_to_vector(png_structp png, png_bytep data, size_t size) {
  auto* out = static_cast<Bytes*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + size);
}

/// Encodes `spec` (bit-packing samples of 1, 2 and 4 bits) as a PNG file in memory.
inline Bytes encode_png(const PngSpec& spec) {
  Bytes out;
  const int channels = png_channels_of(spec.color_type);
  // Pack the rows first, so that nothing with a destructor is created after setjmp.
  const size_t bits_per_row = size_t{spec.width} * channels * spec.bit_depth;
  std::vector<Bytes> rows(spec.height, Bytes((bits_per_row + 7) / 8, 0));
  for (uint32_t y = 0; y < spec.height; ++y) {
    for (size_t i = 0; i < size_t{spec.width} * channels; ++i) {
      const uint16_t v = spec.samples.at(y * size_t{spec.width} * channels + i);
      if (spec.bit_depth == 16) {
        rows[y][2 * i] = static_cast<uint8_t>(v >> 8);
        rows[y][2 * i + 1] = static_cast<uint8_t>(v & 0xff);
      } else if (spec.bit_depth == 8) {
        rows[y][i] = static_cast<uint8_t>(v);
      } else {
        const size_t bit = i * spec.bit_depth;
        rows[y][bit / 8] |= static_cast<uint8_t>(v << (8 - spec.bit_depth - bit % 8));
      }
    }
  }
  std::vector<png_bytep> row_pointers;
  for (Bytes& row : rows) row_pointers.push_back(row.data());

  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return {};
  }
  png_set_write_fn(png, &out, png_write_to_vector, nullptr);
  png_set_IHDR(png, info, spec.width, spec.height, spec.bit_depth, spec.color_type,
               spec.interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (!spec.palette.empty()) {
    png_set_PLTE(png, info, spec.palette.data(), static_cast<int>(spec.palette.size()));
  }
  if (!spec.palette_alpha.empty()) {
    png_set_tRNS(png, info, spec.palette_alpha.data(), static_cast<int>(spec.palette_alpha.size()),
                 nullptr);
  } else if (spec.has_transparent_colour) {
    png_color_16 colour = spec.transparent_colour;
    png_set_tRNS(png, info, nullptr, 0, &colour);
  }
  if (spec.gamma > 0) png_set_gAMA(png, info, spec.gamma);
  if (spec.srgb_chunk) png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_set_rows(png, info, row_pointers.data());
  png_write_png(png, info, PNG_TRANSFORM_IDENTITY, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

// ---- JPEG ---------------------------------------------------------------------------------------

/// Encodes 8-bit gray (channels 1) or RGB (channels 3) pixels as a baseline (or progressive)
/// JPEG in memory.
inline Bytes encode_jpeg(const Bytes& pixels, uint32_t width, uint32_t height, int channels,
                         int quality, bool progressive = false) {
  jpeg_compress_struct cinfo;
  jpeg_error_mgr errors;
  cinfo.err = jpeg_std_error(&errors);
  jpeg_create_compress(&cinfo);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = width;
  cinfo.image_height = height;
  cinfo.input_components = channels;
  cinfo.in_color_space = channels == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  if (progressive) jpeg_simple_progression(&cinfo);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < height) {
    JSAMPROW row =
        const_cast<uint8_t*>(pixels.data()) + size_t{cinfo.next_scanline} * width * channels;
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  Bytes out(buffer, buffer + size);
  jpeg_destroy_compress(&cinfo);
  std::free(buffer);
  return out;
}

// ---- OpenEXR ------------------------------------------------------------------------------------

class VectorOStream final : public Imf::OStream {
 public:
  VectorOStream() : Imf::OStream("memory") {}
  void write(const char c[], int n) override {
    if (at_ + n > out.size()) out.resize(at_ + n);
    std::memcpy(out.data() + at_, c, static_cast<size_t>(n));
    at_ += static_cast<uint64_t>(n);
  }
  uint64_t tellp() override { return at_; }
  void seekp(uint64_t at) override { at_ = at; }
  Bytes out;

 private:
  uint64_t at_ = 0;
};

/// Encodes interleaved float samples with the channel names `names` (e.g. {"R","G","B","A"} or
/// {"Y"}) as an EXR in memory, stored as half or float.
inline Bytes encode_exr(const std::vector<float>& samples, uint32_t width, uint32_t height,
                        const std::vector<std::string>& names, bool as_half,
                        Imf::Compression compression = Imf::ZIP_COMPRESSION) {
  const size_t n = names.size();
  Imf::Header header(static_cast<int>(width), static_cast<int>(height));
  header.compression() = compression;
  Imf::FrameBuffer frame;
  std::vector<half> halves(samples.begin(), samples.end());
  for (size_t c = 0; c < n; ++c) {
    header.channels().insert(names[c], Imf::Channel(as_half ? Imf::HALF : Imf::FLOAT));
    char* base = as_half ? reinterpret_cast<char*>(halves.data() + c)
                         : reinterpret_cast<char*>(const_cast<float*>(samples.data()) + c);
    const size_t size = as_half ? sizeof(half) : sizeof(float);
    frame.insert(names[c],
                 Imf::Slice(as_half ? Imf::HALF : Imf::FLOAT, base, size * n, size * n * width));
  }
  VectorOStream stream;
  {
    Imf::OutputFile file(stream, header);
    file.setFrameBuffer(frame);
    file.writePixels(static_cast<int>(height));
  }
  return stream.out;
}

// ---- Radiance HDR -------------------------------------------------------------------------------

/// The RGBE pixel Radiance writes for a colour: the largest component's exponent is shared.
inline void float_to_rgbe(const float* rgb, uint8_t* out) {
  const float largest = std::max(rgb[0], std::max(rgb[1], rgb[2]));
  if (largest < 1e-32f) {
    out[0] = out[1] = out[2] = out[3] = 0;
    return;
  }
  int exponent = 0;
  const float mantissa = std::frexp(largest, &exponent);  // largest = mantissa * 2^exponent
  const float scale = mantissa * 256.f / largest;
  for (int c = 0; c < 3; ++c) out[c] = static_cast<uint8_t>(rgb[c] * scale);
  out[3] = static_cast<uint8_t>(exponent + 128);
}

/// An HDR file of RGBE pixels (width * height * 4 bytes), with flat or run-length scanlines.
inline Bytes encode_hdr(const Bytes& rgbe, uint32_t width, uint32_t height, bool rle) {
  const std::string header =
      "#?RADIANCE\n# written by the rayfarm tests\nFORMAT=32-bit_rle_rgbe\n"
      "EXPOSURE=1.0\n\n-Y " +
      std::to_string(height) + " +X " + std::to_string(width) + "\n";
  Bytes out(header.begin(), header.end());
  for (uint32_t y = 0; y < height; ++y) {
    const uint8_t* row = rgbe.data() + size_t{y} * width * 4;
    if (!rle) {
      out.insert(out.end(), row, row + size_t{width} * 4);
      continue;
    }
    out.insert(out.end(),
               {2, 2, static_cast<uint8_t>(width >> 8), static_cast<uint8_t>(width & 0xff)});
    for (int c = 0; c < 4; ++c) {
      uint32_t x = 0;
      while (x < width) {
        // A run where at least 3 equal values follow; otherwise a literal stretch up to the next.
        uint32_t run = 1;
        while (x + run < width && run < 127 && row[4 * (x + run) + c] == row[4 * x + c]) ++run;
        if (run >= 3) {
          out.push_back(static_cast<uint8_t>(128 + run));
          out.push_back(row[4 * x + c]);
          x += run;
          continue;
        }
        uint32_t literal = 0;
        while (x + literal < width && literal < 128) {
          uint32_t ahead = 1;
          const uint32_t at = x + literal;
          while (at + ahead < width && ahead < 3 && row[4 * (at + ahead) + c] == row[4 * at + c])
            ++ahead;
          if (ahead >= 3) break;
          ++literal;
        }
        out.push_back(static_cast<uint8_t>(literal));
        for (uint32_t i = 0; i < literal; ++i) out.push_back(row[4 * (x + i) + c]);
        x += literal;
      }
    }
  }
  return out;
}

}  // namespace rayfarm::testing
