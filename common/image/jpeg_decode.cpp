// JPEG from memory with libjpeg. libjpeg reports errors through error_exit, which must not
// return: it longjmps back to the function that called setjmp. Those functions (read_jpeg_header,
// read_jpeg_pixels) hold only plain data; the C++ objects live in decode_jpeg's frame.
#include <cstdio>
// jpeglib.h needs FILE and size_t declared before it.
#include <jpeglib.h>

#include <csetjmp>
#include <cstring>
#include <vector>

#include "common/image/image_formats.h"

namespace rayfarm::image_formats {
namespace {

/// Everything libjpeg and the setjmp frames touch: plain data only.
struct JpegJob {
  jpeg_decompress_struct cinfo;
  jpeg_error_mgr errors;
  jpeg_progress_mgr progress;
  std::jmp_buf jump;
  char error[JMSG_LENGTH_MAX];
  bool created;
  bool unsupported_colour;  ///< CMYK or YCCK
  int channels;
};

[[noreturn]] void on_jpeg_error(j_common_ptr cinfo) {
  auto* job = static_cast<JpegJob*>(cinfo->client_data);
  (*cinfo->err->format_message)(cinfo, job->error);
  std::longjmp(job->jump, 1);
}

/// Warnings (level -1) are corrupt data that libjpeg would paper over (a truncated file becomes
/// grey rows): they are errors here, so that no partial image is returned. Trace messages
/// (level >= 0) are ignored.
void on_jpeg_message(j_common_ptr cinfo, int level) {
  if (level < 0) on_jpeg_error(cinfo);
}

/// A progressive JPEG may hold thousands of nearly empty scans, each a pass over the whole image:
/// a few kilobytes that take minutes to decode. No encoder writes more than a few dozen.
constexpr int kMaxJpegScans = 500;

void on_jpeg_progress(j_common_ptr cinfo) {
  const auto* d = reinterpret_cast<j_decompress_ptr>(cinfo);
  if (d->is_decompressor && d->input_scan_number > kMaxJpegScans) {
    auto* job = static_cast<JpegJob*>(cinfo->client_data);
    std::snprintf(job->error, sizeof(job->error), "more than %d progressive scans", kMaxJpegScans);
    std::longjmp(job->jump, 1);
  }
}

bool read_jpeg_header(JpegJob* job, const uint8_t* data, size_t size) {
  if (setjmp(job->jump)) return false;
  jpeg_create_decompress(&job->cinfo);
  job->created = true;
  job->cinfo.client_data = job;
  job->cinfo.progress = &job->progress;
  jpeg_mem_src(&job->cinfo, data, static_cast<unsigned long>(size));
  if (jpeg_read_header(&job->cinfo, TRUE) != JPEG_HEADER_OK) {
    std::snprintf(job->error, sizeof(job->error), "no image in the data stream");
    return false;
  }
  switch (job->cinfo.jpeg_color_space) {
    case JCS_GRAYSCALE:
      job->cinfo.out_color_space = JCS_GRAYSCALE;
      job->channels = 1;
      break;
    case JCS_CMYK:
    case JCS_YCCK:
      job->unsupported_colour = true;
      break;
    default:  // YCbCr, RGB
      job->cinfo.out_color_space = JCS_RGB;
      job->channels = 3;
      break;
  }
  return true;
}

/// Decodes every scanline into `pixels` (height rows of width * channels bytes).
bool read_jpeg_pixels(JpegJob* job, uint8_t* pixels) {
  if (setjmp(job->jump)) return false;
  jpeg_start_decompress(&job->cinfo);
  if (job->cinfo.output_width != job->cinfo.image_width ||
      job->cinfo.output_height != job->cinfo.image_height ||
      job->cinfo.output_components != job->channels) {
    std::snprintf(job->error, sizeof(job->error), "unexpected output layout");
    return false;
  }
  const size_t row_bytes = size_t{job->cinfo.output_width} * job->cinfo.output_components;
  while (job->cinfo.output_scanline < job->cinfo.output_height) {
    JSAMPROW row = pixels + job->cinfo.output_scanline * row_bytes;
    jpeg_read_scanlines(&job->cinfo, &row, 1);
  }
  jpeg_finish_decompress(&job->cinfo);
  return true;
}

struct JpegGuard {
  JpegJob* job;
  ~JpegGuard() {
    if (job->created) jpeg_destroy_decompress(&job->cinfo);
  }
};

}  // namespace

DecodedImage decode_jpeg(std::span<const uint8_t> bytes, const std::string& name) {
  JpegJob job{};
  job.cinfo.err = jpeg_std_error(&job.errors);
  job.errors.error_exit = on_jpeg_error;
  job.errors.emit_message = on_jpeg_message;
  job.cinfo.client_data = &job;
  job.progress.progress_monitor = on_jpeg_progress;
  JpegGuard guard{&job};
  if (!read_jpeg_header(&job, bytes.data(), bytes.size())) fail(name, "JPEG", job.error);
  if (job.unsupported_colour) {
    fail(name, "JPEG", "CMYK and YCCK images are not supported (RGB and grey are)");
  }
  check_size(name, "JPEG", job.cinfo.image_width, job.cinfo.image_height);
  std::vector<uint8_t> pixels(size_t{job.cinfo.image_width} * job.cinfo.image_height *
                              static_cast<size_t>(job.channels));
  if (!read_jpeg_pixels(&job, pixels.data())) {
    fail(name, "JPEG",
         std::string(job.error) + ", in scanline " + std::to_string(job.cinfo.output_scanline) +
             " of " + std::to_string(job.cinfo.image_height));
  }
  DecodedImage image;
  image.width = job.cinfo.image_width;
  image.height = job.cinfo.image_height;
  image.channels = static_cast<uint32_t>(job.channels);
  image.bytes = std::move(pixels);
  image.display_encoded = true;
  image.format = "JPEG";
  return image;
}

}  // namespace rayfarm::image_formats
