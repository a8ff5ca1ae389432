// PNG from memory with libpng. libpng reports errors by longjmp, so the two functions that call
// setjmp (read_png_header, read_png_pixels) hold only plain data, and every C++ object (the
// pixel buffers, the clean-up guard) lives in decode_png's frame, which no longjmp crosses.
#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <vector>

#include "common/image/image_formats.h"
#include "common/limits.h"

namespace rayfarm::image_formats {
namespace {

/// Everything libpng's callbacks and the setjmp frames touch: plain data only.
struct PngJob {
  const uint8_t* data;
  size_t size;
  size_t at;  ///< bytes consumed so far, for messages
  png_structp png;
  png_infop info;
  char error[256];
  // The header, as read, then as transformed.
  png_uint_32 width, height;
  int color_type, bit_depth, interlace;
  bool display_encoded;
  int channels, out_bit_depth;
  size_t row_bytes;
};

void on_png_error(png_structp png, png_const_charp message) {
  auto* job = static_cast<PngJob*>(png_get_error_ptr(png));
  std::snprintf(job->error, sizeof(job->error), "%s", message);
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

void on_png_read(png_structp png, png_bytep out, size_t count) {
  auto* job = static_cast<PngJob*>(png_get_io_ptr(png));
  if (count > job->size - job->at) png_error(png, "the file ends early");
  std::memcpy(out, job->data + job->at, count);
  job->at += count;
}

/// Reads the chunks before the pixels and the image's header. False with job->error set when
/// libpng fails.
bool read_png_header(PngJob* job) {
  if (setjmp(png_jmpbuf(job->png))) return false;
  png_set_read_fn(job->png, job, on_png_read);
  // libpng refuses larger headers itself, before it allocates rows for them.
  png_set_user_limits(job->png, kMaxTextureSide, kMaxTextureSide);
  png_read_info(job->png, job->info);
  png_get_IHDR(job->png, job->info, &job->width, &job->height, &job->bit_depth, &job->color_type,
               &job->interlace, nullptr, nullptr);
  // An sRGB chunk wins; otherwise a gAMA of 1.0 (within 1%) marks linear samples. Any other
  // gamma is taken as sRGB, which it approximates (2.2 being the usual value).
  job->display_encoded = true;
  png_fixed_point gamma = 0;
  if (!png_get_valid(job->png, job->info, PNG_INFO_sRGB) &&
      png_get_gAMA_fixed(job->png, job->info, &gamma) != 0 && gamma >= 99000 && gamma <= 101000) {
    job->display_encoded = false;
  }
  return true;
}

/// Sets up the transformations (palette to RGB, 1/2/4 bits to 8, tRNS to alpha, interlacing)
/// and learns the layout they give.
bool read_png_layout(PngJob* job) {
  if (setjmp(png_jmpbuf(job->png))) return false;
  png_set_expand(job->png);
  png_set_interlace_handling(job->png);
  png_read_update_info(job->png, job->info);
  job->channels = png_get_channels(job->png, job->info);
  job->out_bit_depth = png_get_bit_depth(job->png, job->info);
  job->row_bytes = png_get_rowbytes(job->png, job->info);
  return true;
}

/// Reads every row (all passes of an interlaced image) and the chunks after them up to IEND.
bool read_png_rows(PngJob* job, png_bytepp rows) {
  if (setjmp(png_jmpbuf(job->png))) return false;
  png_read_image(job->png, rows);
  png_read_end(job->png, nullptr);
  return true;
}

/// Destroys the libpng structures whichever way decode_png leaves.
struct PngGuard {
  PngJob* job;
  ~PngGuard() { png_destroy_read_struct(&job->png, &job->info, nullptr); }
};

}  // namespace

DecodedImage decode_png(std::span<const uint8_t> bytes, const std::string& name) {
  // The size in IHDR, checked here for a clear message; libpng's own limit is a second line.
  if (bytes.size() >= 24 && std::memcmp(bytes.data() + 12, "IHDR", 4) == 0) {
    auto be32 = [&](size_t at) {
      return (uint32_t{bytes[at]} << 24) | (uint32_t{bytes[at + 1]} << 16) |
             (uint32_t{bytes[at + 2]} << 8) | bytes[at + 3];
    };
    check_size(name, "PNG", be32(16), be32(20));
  }
  PngJob job{};
  job.data = bytes.data();
  job.size = bytes.size();
  job.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &job, on_png_error, on_png_warning);
  if (job.png != nullptr) job.info = png_create_info_struct(job.png);
  PngGuard guard{&job};
  if (job.info == nullptr) fail(name, "PNG", "libpng could not start (out of memory)");
  auto failed = [&] {
    fail(name, "PNG",
         std::string(job.error) + ", at byte " + std::to_string(job.at) + " of " +
             std::to_string(job.size));
  };
  if (!read_png_header(&job)) failed();
  check_size(name, "PNG", job.width, job.height);
  if (!read_png_layout(&job)) failed();
  const bool layout_ok =
      job.channels >= 1 && job.channels <= 4 &&
      (job.out_bit_depth == 8 || job.out_bit_depth == 16) &&
      job.row_bytes == size_t{job.width} * job.channels * (job.out_bit_depth / 8);
  if (!layout_ok) fail(name, "PNG", "unexpected sample layout after libpng's transformations");
  std::vector<uint8_t> raw(job.row_bytes * job.height);
  std::vector<png_bytep> rows(job.height);
  for (size_t y = 0; y < job.height; ++y) rows[y] = raw.data() + y * job.row_bytes;
  if (!read_png_rows(&job, rows.data())) failed();

  DecodedImage image;
  image.width = job.width;
  image.height = job.height;
  image.channels = static_cast<uint32_t>(job.channels);
  image.display_encoded = job.display_encoded;
  image.format = "PNG";
  if (job.out_bit_depth == 8) {
    image.bytes = std::move(raw);
  } else {
    image.floats.resize(raw.size() / 2);
    for (size_t i = 0; i < image.floats.size(); ++i) {
      const unsigned v = (unsigned{raw[2 * i]} << 8) | raw[2 * i + 1];  // PNG is big-endian
      image.floats[i] = static_cast<float>(v) / 65535.f;
    }
  }
  return image;
}

}  // namespace rayfarm::image_formats
