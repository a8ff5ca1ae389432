// Writes the image seed corpus (fuzz/corpus/image/): tiny valid PNG, JPEG, OpenEXR and Radiance
// HDR files and a few broken ones, with the same writers as the decoder tests. Run by
// fuzz/make_seeds.sh with the corpus folder as its argument.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/support/image_writers.h"

namespace {

using rayfarm::testing::Bytes;

void write(const std::filesystem::path& dir, const std::string& name, const Bytes& bytes) {
  std::ofstream(dir / name, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

Bytes cut(Bytes bytes, size_t keep) {
  bytes.resize(std::min(keep, bytes.size()));
  return bytes;
}

}  // namespace

int main(int argc, char** argv) {
  namespace t = rayfarm::testing;
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_image_seeds CORPUS_FOLDER\n");
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  std::filesystem::create_directories(dir);

  t::PngSpec rgba;
  rgba.width = 3, rgba.height = 2, rgba.color_type = PNG_COLOR_TYPE_RGB_ALPHA;
  rgba.interlaced = true;
  for (int i = 0; i < 3 * 2 * 4; ++i) rgba.samples.push_back(static_cast<uint16_t>(i * 11));
  const Bytes png = t::encode_png(rgba);
  write(dir, "rgba-interlaced.png", png);
  t::PngSpec palette;
  palette.width = 4, palette.height = 2, palette.color_type = PNG_COLOR_TYPE_PALETTE;
  palette.bit_depth = 2;
  palette.palette = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}};
  palette.palette_alpha = {128};
  palette.samples = {0, 1, 2, 0, 2, 1, 0, 1};
  write(dir, "palette-trns.png", t::encode_png(palette));
  t::PngSpec gray16;
  gray16.width = 2, gray16.height = 2, gray16.color_type = PNG_COLOR_TYPE_GRAY;
  gray16.bit_depth = 16, gray16.gamma = 1.0;
  gray16.samples = {0, 1000, 40000, 65535};
  write(dir, "gray16-linear.png", t::encode_png(gray16));
  write(dir, "truncated.png", cut(png, png.size() / 2));

  Bytes pixels;
  for (int i = 0; i < 8 * 8 * 3; ++i) pixels.push_back(static_cast<uint8_t>(i * 5));
  const Bytes jpeg = t::encode_jpeg(pixels, 8, 8, 3, 75);
  write(dir, "rgb.jpg", jpeg);
  write(dir, "gray-progressive.jpg", t::encode_jpeg(pixels, 8, 8, 1, 75, true));
  write(dir, "truncated.jpg", cut(jpeg, jpeg.size() - 40));

  const std::vector<float> samples = {0.f,  0.5f, 1.f,  1.f, 2.f,  4.f,   8.f, 0.5f,
                                      16.f, 0.1f, 0.2f, 1.f, 1e3f, 1e-3f, 0.f, 0.f};
  write(dir, "half-rgba.exr", t::encode_exr(samples, 2, 2, {"R", "G", "B", "A"}, true));
  write(dir, "float-y.exr",
        t::encode_exr({0.f, 1.f, 2.f, 3.f}, 2, 2, {"Y"}, false, Imf::NO_COMPRESSION));

  Bytes rgbe;
  for (int i = 0; i < 8 * 2; ++i) {
    rgbe.insert(rgbe.end(), {200, static_cast<uint8_t>(i * 9), 17, static_cast<uint8_t>(120 + i)});
  }
  write(dir, "flat.hdr", t::encode_hdr(rgbe, 8, 2, false));
  const Bytes rle = t::encode_hdr(rgbe, 8, 2, true);
  write(dir, "rle.hdr", rle);
  write(dir, "truncated.hdr", cut(rle, rle.size() - 5));
  const std::string flipped = "#?RADIANCE\n\n+Y 1 +X 1\n\x80\x80\x80\x80";
  write(dir, "orientation.hdr", Bytes(flipped.begin(), flipped.end()));
  std::printf("image seeds written to %s\n", dir.c_str());
  return 0;
}
