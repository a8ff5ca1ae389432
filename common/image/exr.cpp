#include "common/image/exr.h"

#include "common/image/exr_header.h"
#include "common/util/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <exception>
#include <fstream>
#include <optional>
#include <system_error>

#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

/// A name beside `path` that no other writer in this process or another one uses.
[[noreturn]] void fail_read(const fs::path& path, const std::string& cause) {
  throw ImageError("cannot read " + path.string() + ": " + cause);
}

/// Checks the sizes of `image`; the message names the first inconsistency.
void check_image_shape(const Image& image) {
  if (image.width == 0 || image.height == 0) {
    throw ImageError("empty image (" + std::to_string(image.width) + "x" +
                     std::to_string(image.height) + ")");
  }
  const size_t pixels = size_t{image.width} * image.height;
  if (image.rgb.size() != pixels * 3) {
    throw ImageError("image has " + std::to_string(image.rgb.size()) + " RGB values, expected " +
                     std::to_string(pixels * 3));
  }
  for (const auto& [name, values] : image.extra) {
    if (name.empty() || name == "R" || name == "G" || name == "B") {
      throw ImageError("invalid extra channel name '" + name + "'");
    }
    if (values.size() != pixels) {
      throw ImageError("channel '" + name + "' has " + std::to_string(values.size()) +
                       " values, expected " + std::to_string(pixels));
    }
  }
}

/// Writes `image` as a ZIP-compressed float32 EXR; OpenEXR (Iex) errors propagate.
void write_exr_file(const fs::path& file, const Image& image) {
  const int width = static_cast<int>(image.width);
  const int height = static_cast<int>(image.height);
  Imf::Header header(width, height);
  header.compression() = Imf::ZIP_COMPRESSION;
  for (const auto& [name, value] : image.attributes) {
    header.insert(name, Imf::StringAttribute(value));
  }

  Imf::FrameBuffer frame;
  const Imath::Box2i window = header.dataWindow();
  const size_t rgb_stride = 3 * sizeof(float);
  const char* rgb_names[3] = {"R", "G", "B"};
  for (int c = 0; c < 3; ++c) {
    header.channels().insert(rgb_names[c], Imf::Channel(Imf::FLOAT));
    frame.insert(rgb_names[c], Imf::Slice::Make(Imf::FLOAT, image.rgb.data() + c, window,
                                                rgb_stride, rgb_stride * image.width));
  }
  for (const auto& [name, values] : image.extra) {
    header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    frame.insert(name, Imf::Slice::Make(Imf::FLOAT, values.data(), window, sizeof(float),
                                        sizeof(float) * image.width));
  }

  // The destructor writes the line offset table and closes the file.
  Imf::OutputFile out(file.c_str(), header);
  out.setFrameBuffer(frame);
  out.writePixels(height);
}

/// The data window's size from the header of the EXR at `path` (peek_exr_data_window over its
/// first MiB).
std::optional<std::pair<int64_t, int64_t>> peek_data_window(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string head(size_t{1} << 20, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  return peek_exr_data_window(head);
}

/// Reads the whole EXR at `path`; OpenEXR (Iex) errors propagate.
Image read_exr_file(const fs::path& path, const ExrExpect& expect) {
  // A header may claim any size: compare it with what is expected before OpenEXR allocates for
  // it (its offset table) and before the pixels are allocated below.
  auto size_mismatch = [&](int64_t width, int64_t height) {
    return expect.width != 0 && (width != expect.width || height != expect.height);
  };
  auto refuse_size = [&](int64_t width, int64_t height) {
    fail_read(path, "its header says " + std::to_string(width) + "x" + std::to_string(height) +
                        ", the image is " + std::to_string(expect.width) + "x" +
                        std::to_string(expect.height));
  };
  if (expect.width != 0) {
    const auto peeked = peek_data_window(path);
    if (!peeked) {
      fail_read(path,
                "not an OpenEXR file with a readable header and data window in its first "
                "MiB");
    }
    if (size_mismatch(peeked->first, peeked->second)) refuse_size(peeked->first, peeked->second);
  }
  Imf::InputFile in(path.c_str());
  const Imf::Header& header = in.header();
  const Imath::Box2i data = header.dataWindow();
  const Imath::Box2i display = header.displayWindow();
  if (data != display) {
    fail_read(path,
              "data window differs from display window (cropped or overscan images are "
              "not supported)");
  }
  const int64_t width = int64_t{data.max.x} - data.min.x + 1;
  const int64_t height = int64_t{data.max.y} - data.min.y + 1;
  if (width <= 0 || height <= 0 || width > UINT32_MAX || height > UINT32_MAX) {
    fail_read(path, "invalid data window");
  }
  if (size_mismatch(width, height)) refuse_size(width, height);

  Image image;
  image.width = static_cast<uint32_t>(width);
  image.height = static_cast<uint32_t>(height);
  const size_t pixels = size_t{image.width} * image.height;
  const Imf::ChannelList& channels = header.channels();
  for (const char* name : {"R", "G", "B"}) {
    if (channels.findChannel(name) == nullptr) {
      fail_read(path, std::string("no ") + name + " channel");
    }
  }
  for (auto it = channels.begin(); it != channels.end(); ++it) {
    if (it.channel().xSampling != 1 || it.channel().ySampling != 1) {
      fail_read(path, std::string("channel '") + it.name() + "' is subsampled");
    }
  }

  // Slices are positioned in the data window's coordinates; OpenEXR converts any pixel type.
  Imf::FrameBuffer frame;
  image.rgb.assign(pixels * 3, 0.f);
  const size_t rgb_stride = 3 * sizeof(float);
  const char* rgb_names[3] = {"R", "G", "B"};
  for (int c = 0; c < 3; ++c) {
    frame.insert(rgb_names[c], Imf::Slice::Make(Imf::FLOAT, image.rgb.data() + c, data, rgb_stride,
                                                rgb_stride * image.width));
  }
  for (auto it = channels.begin(); it != channels.end(); ++it) {
    const std::string name = it.name();
    if (name == "R" || name == "G" || name == "B") continue;
    if (expect.rgb_only) continue;
    std::vector<float>& values = image.extra[name];
    values.assign(pixels, 0.f);
    frame.insert(name, Imf::Slice::Make(Imf::FLOAT, values.data(), data, sizeof(float),
                                        sizeof(float) * image.width));
  }
  in.setFrameBuffer(frame);
  if (!in.isComplete()) fail_read(path, "the file is truncated (missing pixel data)");
  in.readPixels(data.min.y, data.max.y);

  for (auto it = header.begin(); it != header.end(); ++it) {
    if (const auto* text = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) {
      image.attributes[it.name()] = text->value();
    }
  }
  return image;
}

}  // namespace

void write_exr(const fs::path& path, const Image& image) {
  try {
    check_image_shape(image);
  } catch (const ImageError& e) {
    throw ImageError("cannot write " + path.string() + ": " + e.what());
  }
  try {
    write_atomically(path, [&](const fs::path& temporary) { write_exr_file(temporary, image); });
  } catch (const std::runtime_error& e) {
    throw ImageError(e.what());
  }
}

Image read_exr(const fs::path& path, const ExrExpect& expect) {
  std::error_code ec;
  if (!fs::exists(path, ec)) fail_read(path, "no such file");
  if (fs::is_directory(path, ec)) fail_read(path, "is a directory");
  try {
    return read_exr_file(path, expect);
  } catch (const ImageError&) {
    throw;
  } catch (const std::exception& e) {
    // Iex exceptions (invalid header, unexpected end of file, ...) derive from std::exception.
    fail_read(path, e.what());
  }
}

}  // namespace rayfarm
