// OpenEXR from memory: an Imf::IStream over the bytes, and the first part's R, G, B (and A) or
// Y (and A) channels read as float, whatever their stored type (half, float, uint).
#include <algorithm>
#include <cstring>
#include <exception>
#include <string_view>

#include <Iex.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>

#include "common/image/exr_header.h"
#include "common/image/image_formats.h"
#include "common/scene/scene_files.h"

namespace rayfarm::image_formats {
namespace {

/// The file's bytes as an OpenEXR input stream; reading past the end throws, as a file would.
class ByteStream final : public Imf::IStream {
 public:
  ByteStream(std::span<const uint8_t> bytes, const std::string& name)
      : Imf::IStream(name.c_str()), bytes_(bytes) {}

  bool read(char out[], int count) override {
    if (count < 0 || static_cast<uint64_t>(count) > bytes_.size() - std::min(at_, bytes_.size())) {
      throw Iex::InputExc("the file ends early, at byte " + std::to_string(bytes_.size()));
    }
    std::memcpy(out, bytes_.data() + at_, static_cast<size_t>(count));
    at_ += static_cast<uint64_t>(count);
    return at_ < bytes_.size();
  }
  uint64_t tellg() override { return at_; }
  void seekg(uint64_t at) override { at_ = at; }

 private:
  std::span<const uint8_t> bytes_;
  uint64_t at_ = 0;
};

DecodedImage read_exr_bytes(std::span<const uint8_t> bytes, const std::string& name) {
  const std::string_view head(reinterpret_cast<const char*>(bytes.data()),
                              std::min(bytes.size(), size_t{1} << 20));
  const auto window = peek_exr_data_window(head);
  if (!window) fail(name, "OpenEXR", "no complete header with a data window in the first MiB");
  check_size(name, "OpenEXR", window->first, window->second);

  ByteStream stream(bytes, name);
  Imf::InputFile in(stream);
  const Imath::Box2i data = in.header().dataWindow();
  const int64_t width = int64_t{data.max.x} - data.min.x + 1;
  const int64_t height = int64_t{data.max.y} - data.min.y + 1;
  check_size(name, "OpenEXR", width, height);

  const Imf::ChannelList& list = in.header().channels();
  auto has = [&](const char* channel) { return list.findChannel(channel) != nullptr; };
  std::vector<const char*> names;
  if (has("R") && has("G") && has("B")) {
    names = {"R", "G", "B"};
  } else if (has("Y")) {
    if (has("RY") || has("BY")) {
      fail(name, "OpenEXR", "luminance/chroma images (Y, RY, BY) are not supported");
    }
    names = {"Y"};
  } else {
    fail(name, "OpenEXR", "no R, G, B channels and no Y channel");
  }
  if (has("A")) names.push_back("A");
  for (const char* channel : names) {
    const Imf::Channel* c = list.findChannel(channel);
    if (c->xSampling != 1 || c->ySampling != 1) {
      fail(name, "OpenEXR", std::string("channel ") + channel + " is subsampled");
    }
  }
  if (!in.isComplete()) fail(name, "OpenEXR", "the file is truncated (pixel data missing)");

  DecodedImage image;
  image.width = static_cast<uint32_t>(width);
  image.height = static_cast<uint32_t>(height);
  image.channels = static_cast<uint32_t>(names.size());
  image.floats.assign(size_t{image.width} * image.height * image.channels, 0.f);
  image.format = "OpenEXR";
  const size_t pixel_stride = sizeof(float) * image.channels;
  Imf::FrameBuffer frame;
  for (size_t c = 0; c < names.size(); ++c) {
    frame.insert(names[c], Imf::Slice::Make(Imf::FLOAT, image.floats.data() + c, data, pixel_stride,
                                            pixel_stride * image.width));
  }
  in.setFrameBuffer(frame);
  in.readPixels(data.min.y, data.max.y);
  return image;
}

}  // namespace

DecodedImage decode_exr(std::span<const uint8_t> bytes, const std::string& name) {
  try {
    return read_exr_bytes(bytes, name);
  } catch (const SceneError&) {
    throw;
  } catch (const std::exception& e) {
    // OpenEXR (Iex) errors: invalid header, corrupt or missing pixel data, ...
    fail(name, "OpenEXR", e.what());
  }
}

}  // namespace rayfarm::image_formats
