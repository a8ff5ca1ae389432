#include "common/image/png.h"

#include "common/util/atomic_file.h"

#include <png.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace rayfarm {
namespace {

/// Everything the libpng writer needs, plain data only: libpng reports errors with longjmp, so
/// the frame that calls setjmp must hold no object with a destructor.
struct PngWriteJob {
  const char* path;
  const uint8_t* pixels;  ///< 8-bit RGB, row-major
  uint32_t width;
  uint32_t height;
  char error[256];  ///< the cause, when writing fails
};

void on_png_error(png_structp png, png_const_charp message) {
  auto* job = static_cast<PngWriteJob*>(png_get_error_ptr(png));
  std::snprintf(job->error, sizeof(job->error), "libpng: %s", message);
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

/// Writes job->pixels to job->path. Returns false with job->error set on failure.
bool write_png_file(PngWriteJob* job) {
  std::FILE* file = std::fopen(job->path, "wb");
  if (file == nullptr) {
    std::snprintf(job->error, sizeof(job->error), "%s", std::strerror(errno));
    return false;
  }
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, job, on_png_error, on_png_warning);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  if (info == nullptr) {
    std::snprintf(job->error, sizeof(job->error), "libpng: out of memory");
    png_destroy_write_struct(&png, nullptr);
    std::fclose(file);
    return false;
  }
  // `png`, `info` and `file` are not modified after setjmp, so they are valid after a longjmp.
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    std::fclose(file);
    return false;
  }
  png_init_io(png, file);
  png_set_IHDR(png, info, job->width, job->height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  for (uint32_t y = 0; y < job->height; ++y) {
    png_write_row(png, job->pixels + size_t{y} * job->width * 3);
  }
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);

  const bool flushed = std::fflush(file) == 0 && std::ferror(file) == 0;
  const int flush_errno = errno;
  if (std::fclose(file) != 0 || !flushed) {
    std::snprintf(job->error, sizeof(job->error), "%s",
                  std::strerror(flushed ? errno : flush_errno));
    return false;
  }
  return true;
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
double srgb_encode(double linear) {
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
}

/// Maps a linear value to an 8-bit sRGB code: exposure, clamp to [0, 1], encode, round.
uint8_t to_srgb8(float linear, float exposure) {
  double v = std::isfinite(linear) ? static_cast<double>(linear) * exposure : 0.0;
  if (std::isnan(v)) v = 0.0;  // 0 * inf exposure
  v = std::clamp(v, 0.0, 1.0);
  return static_cast<uint8_t>(std::lround(srgb_encode(v) * 255.0));
}

}  // namespace

std::vector<uint8_t> preview_pixels(const Image& image, float exposure) {
  std::vector<uint8_t> pixels(image.rgb.size());
  std::transform(image.rgb.begin(), image.rgb.end(), pixels.begin(),
                 [exposure](float v) { return to_srgb8(v, exposure); });
  return pixels;
}

void write_png_preview(const std::filesystem::path& path, const Image& image, float exposure) {
  const size_t values = size_t{image.width} * image.height * 3;
  if (image.width == 0 || image.height == 0 || image.rgb.size() != values) {
    throw ImageError("cannot write " + path.string() + ": invalid image (" +
                     std::to_string(image.width) + "x" + std::to_string(image.height) + ", " +
                     std::to_string(image.rgb.size()) + " RGB values)");
  }
  write_png_rgb8(path, preview_pixels(image, exposure), image.width, image.height);
}

void write_png_rgb8(const std::filesystem::path& path, const std::vector<uint8_t>& rgb,
                    uint32_t width, uint32_t height) {
  if (width == 0 || height == 0 || rgb.size() != size_t{width} * height * 3) {
    throw ImageError("cannot write " + path.string() + ": invalid image (" +
                     std::to_string(width) + "x" + std::to_string(height) + ", " +
                     std::to_string(rgb.size()) + " bytes)");
  }
  try {
    write_atomically(path, [&](const std::filesystem::path& temporary) {
      const std::string name = temporary.string();
      PngWriteJob job{name.c_str(), rgb.data(), width, height, {}};
      if (!write_png_file(&job)) throw ImageError(job.error);
    });
  } catch (const std::runtime_error& e) {
    throw ImageError(e.what());
  }
}

}  // namespace rayfarm
