// EXR and PNG files, atomic writes, read errors, and the image metrics.
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>
#include <half.h>

#include "common/image/exr.h"
#include "common/image/exr_header.h"
#include "common/image/metrics.h"
#include "common/image/png.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

uint32_t bits_of(float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof(bits));
  return bits;
}

std::vector<uint32_t> bits_of(const std::vector<float>& values) {
  std::vector<uint32_t> bits;
  for (float v : values) bits.push_back(bits_of(v));
  return bits;
}

Image make_image(uint32_t width, uint32_t height, std::vector<float> rgb) {
  Image image;
  image.width = width;
  image.height = height;
  image.rgb = std::move(rgb);
  return image;
}

/// Files in `dir`, by name.
std::vector<std::string> list_dir(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir))
    names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

/// A fresh directory per test, removed afterwards.
class ImageFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("rayfarm-" + std::string(info->test_suite_name()) + "-" +
                                        info->name() + "-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

/// Expects `call` to throw ImageError whose message contains every string of `needles`.
template <typename Call>
void expect_image_error(Call call, const std::vector<std::string>& needles) {
  try {
    call();
    ADD_FAILURE() << "no ImageError thrown";
  } catch (const ImageError& e) {
    for (const auto& needle : needles) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
          << "'" << e.what() << "' does not mention '" << needle << "'";
    }
  }
}

/// Writes an EXR directly with OpenEXR, FLOAT or HALF: channel c holds c * 100 + index + 0.5
/// (exact in half too), returned in `values` as float.
void write_raw_exr(const fs::path& path, const Imath::Box2i& display, const Imath::Box2i& data,
                   const std::vector<std::string>& channels, Imf::PixelType type,
                   std::vector<std::vector<float>>& values) {
  Imf::Header header(display, data);
  Imf::FrameBuffer frame;
  const int width = data.max.x - data.min.x + 1;
  const int height = data.max.y - data.min.y + 1;
  values.assign(channels.size(), std::vector<float>(size_t(width) * height));
  std::vector<std::vector<half>> halves(channels.size());
  for (size_t c = 0; c < channels.size(); ++c) {
    for (size_t i = 0; i < values[c].size(); ++i) values[c][i] = float(c * 100 + i) + 0.5f;
    header.channels().insert(channels[c], Imf::Channel(type));
    if (type == Imf::HALF) {
      halves[c].assign(values[c].begin(), values[c].end());
      frame.insert(channels[c], Imf::Slice::Make(Imf::HALF, halves[c].data(), data, sizeof(half),
                                                 sizeof(half) * width));
    } else {
      frame.insert(channels[c], Imf::Slice::Make(Imf::FLOAT, values[c].data(), data, sizeof(float),
                                                 sizeof(float) * width));
    }
  }
  Imf::OutputFile out(path.c_str(), header);
  out.setFrameBuffer(frame);
  out.writePixels(height);
}

using ExrTest = ImageFileTest;

TEST_F(ExrTest, RoundTripIsBitExact) {
  const float denorm = std::numeric_limits<float>::denorm_min();
  const float inf = std::numeric_limits<float>::infinity();
  Image image = make_image(3, 2,
                           {1e30f, 1e-30f, 65504.f * 2, -0.f, denorm, 1e-40f,  //
                            -denorm, 0.1f, -3.75f, inf, -inf, 1.f,             //
                            std::numeric_limits<float>::max(), 0.f, 1e-20f,    //
                            65504.f, 65520.f, -1e30f});
  image.extra["albedo.R"] = {0.f, 0.25f, 1e-38f, -0.f, 7.f, 1e25f};
  image.extra["variance"] = {1.f, 2.f, 3.f, 4.f, 5.f, denorm};
  image.attributes["rayfarm.scene"] = "scenes/cornell.json";
  image.attributes["rayfarm.spp"] = "1024";

  const fs::path path = dir_ / "round.exr";
  write_exr(path, image);
  const Image back = read_exr(path);

  ASSERT_EQ(back.width, 3u);
  ASSERT_EQ(back.height, 2u);
  EXPECT_EQ(bits_of(back.rgb), bits_of(image.rgb));
  ASSERT_EQ(back.extra.size(), 2u);
  EXPECT_EQ(bits_of(back.extra.at("albedo.R")), bits_of(image.extra.at("albedo.R")));
  EXPECT_EQ(bits_of(back.extra.at("variance")), bits_of(image.extra.at("variance")));
  EXPECT_EQ(back.attributes.at("rayfarm.scene"), "scenes/cornell.json");
  EXPECT_EQ(back.attributes.at("rayfarm.spp"), "1024");
}

// The header read without OpenEXR: every attribute OpenEXR wrote, string attributes as their
// bytes, the data window's size; a header cut short is no header.
TEST_F(ExrTest, AHeaderIsReadWithoutOpenExr) {
  Image image = make_image(3, 2, std::vector<float>(18, 0.5f));
  image.attributes["rayfarm:spp"] = "1024";
  const fs::path path = dir_ / "peek.exr";
  write_exr(path, image);
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto attributes = peek_exr_attributes(bytes);
  ASSERT_TRUE(attributes);
  bool spp = false, window = false;
  for (const ExrAttribute& a : *attributes) {
    if (a.name == "rayfarm:spp") {
      EXPECT_EQ(a.type, "string");
      EXPECT_EQ(a.value, "1024");
      spp = true;
    }
    window = window || a.name == "dataWindow";
  }
  EXPECT_TRUE(spp);
  EXPECT_TRUE(window);
  EXPECT_EQ(peek_exr_data_window(bytes), (std::pair<int64_t, int64_t>{3, 2}));
  // Cut inside the header (its last attribute), or not an EXR at all.
  const size_t end = bytes.find(std::string("rayfarm:spp")) + 12;
  EXPECT_FALSE(peek_exr_attributes(std::string_view(bytes).substr(0, end)));
  EXPECT_FALSE(peek_exr_attributes("not an exr file"));
  EXPECT_FALSE(peek_exr_data_window(std::string_view(bytes).substr(0, 8)));
}

TEST_F(ExrTest, ReadsHalfChannelsAsFloat) {
  const fs::path path = dir_ / "half.exr";
  const Imath::Box2i window({0, 0}, {3, 1});
  std::vector<std::vector<float>> values;
  write_raw_exr(path, window, window, {"R", "G", "B", "Z"}, Imf::HALF, values);

  const Image image = read_exr(path);
  ASSERT_EQ(image.width, 4u);
  ASSERT_EQ(image.height, 2u);
  for (size_t i = 0; i < 8; ++i) {
    for (size_t c = 0; c < 3; ++c) EXPECT_EQ(image.rgb[i * 3 + c], values[c][i]);  // exact in half
    EXPECT_EQ(image.extra.at("Z")[i], values[3][i]);
  }
}

TEST_F(ExrTest, ReadsAnOffsetDataWindow) {
  const fs::path path = dir_ / "offset.exr";
  const Imath::Box2i window({10, -4}, {12, -3});  // 3x2, not at the origin
  std::vector<std::vector<float>> values;
  write_raw_exr(path, window, window, {"R", "G", "B"}, Imf::FLOAT, values);

  const Image image = read_exr(path);
  ASSERT_EQ(image.width, 3u);
  ASSERT_EQ(image.height, 2u);
  for (size_t i = 0; i < 6; ++i) {
    for (size_t c = 0; c < 3; ++c) EXPECT_EQ(image.rgb[i * 3 + c], values[c][i]) << i;
  }
}

TEST_F(ExrTest, RejectsDataWindowUnlikeDisplayWindow) {
  const fs::path path = dir_ / "crop.exr";
  std::vector<std::vector<float>> values;
  write_raw_exr(path, Imath::Box2i({0, 0}, {7, 7}), Imath::Box2i({2, 2}, {4, 4}), {"R", "G", "B"},
                Imf::FLOAT, values);
  expect_image_error([&] { read_exr(path); }, {path.string(), "data window"});
}

TEST_F(ExrTest, RejectsMissingRgbChannel) {
  const fs::path path = dir_ / "luminance.exr";
  const Imath::Box2i window({0, 0}, {1, 1});
  std::vector<std::vector<float>> values;
  write_raw_exr(path, window, window, {"R", "G", "Y"}, Imf::FLOAT, values);
  expect_image_error([&] { read_exr(path); }, {path.string(), "no B channel"});
}

TEST_F(ExrTest, AtomicWriteLeavesOnlyTheTarget) {
  const fs::path path = dir_ / "out.exr";
  write_exr(path, make_image(2, 1, {1, 2, 3, 4, 5, 6}));
  write_exr(path, make_image(1, 1, {7, 8, 9}));  // replaces the first
  EXPECT_EQ(list_dir(dir_), std::vector<std::string>{"out.exr"});
  EXPECT_EQ(read_exr(path).rgb, (std::vector<float>{7, 8, 9}));
}

TEST_F(ExrTest, WriteIntoMissingDirectoryThrowsAndLeavesNoFile) {
  const fs::path path = dir_ / "no-such-dir" / "out.exr";
  const Image image = make_image(1, 1, {1, 2, 3});
  expect_image_error([&] { write_exr(path, image); }, {path.string(), "No such file"});
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(list_dir(dir_).empty());
}

TEST_F(ExrTest, FailedRenameRemovesTheTemporary) {
  const fs::path path = dir_ / "taken.exr";
  fs::create_directories(path / "child");  // a non-empty directory cannot be replaced by a file
  expect_image_error([&] { write_exr(path, make_image(1, 1, {1, 2, 3})); }, {path.string()});
  EXPECT_EQ(list_dir(dir_), std::vector<std::string>{"taken.exr"});
}

TEST_F(ExrTest, RejectsMalformedImageWithoutWriting) {
  const fs::path path = dir_ / "bad.exr";
  expect_image_error([&] { write_exr(path, make_image(2, 2, {1, 2, 3})); }, {path.string()});
  Image image = make_image(1, 1, {1, 2, 3});
  image.extra["depth"] = {1.f, 2.f};
  expect_image_error([&] { write_exr(path, image); }, {path.string(), "depth"});
  EXPECT_TRUE(list_dir(dir_).empty());
}

TEST_F(ExrTest, ReadOfMissingFileNamesIt) {
  const fs::path path = dir_ / "absent.exr";
  expect_image_error([&] { read_exr(path); }, {path.string(), "no such file"});
}

TEST_F(ExrTest, ReadOfTextFileNamesIt) {
  const fs::path path = dir_ / "notes.exr";
  std::ofstream(path) << "this is not an image\n";
  expect_image_error([&] { read_exr(path); }, {path.string()});
}

TEST_F(ExrTest, ReadOfTruncatedFileNamesIt) {
  const fs::path full = dir_ / "full.exr";
  Image image = make_image(64, 64, std::vector<float>(64 * 64 * 3));
  for (size_t i = 0; i < image.rgb.size(); ++i) image.rgb[i] = std::sin(float(i)) * 1000.f;
  write_exr(full, image);
  std::ifstream in(full, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 1000u);

  for (size_t keep : {size_t{0}, size_t{10}, size_t{200}, bytes.size() / 2, bytes.size() - 1}) {
    const fs::path path = dir_ / ("cut-" + std::to_string(keep) + ".exr");
    std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(keep));
    SCOPED_TRACE("kept " + std::to_string(keep) + " of " + std::to_string(bytes.size()));
    expect_image_error([&] { read_exr(path); }, {path.string()});
  }
}

/// The sRGB code of a linear value, computed independently of png.cpp.
int srgb8(double linear) {
  linear = std::min(std::max(linear, 0.0), 1.0);
  const double encoded =
      linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1 / 2.4) - 0.055;
  return int(std::floor(encoded * 255 + 0.5));
}

/// Reads an 8-bit RGB PNG with libpng's simplified API.
std::vector<uint8_t> read_png_rgb(const fs::path& path, uint32_t& width, uint32_t& height) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    ADD_FAILURE() << "libpng cannot read " << path << ": " << image.message;
    return {};
  }
  image.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> pixels(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr)) {
    ADD_FAILURE() << "libpng cannot decode " << path << ": " << image.message;
    return {};
  }
  width = image.width;
  height = image.height;
  return pixels;
}

using PngTest = ImageFileTest;

TEST_F(PngTest, WritesSrgbEncodedPixels) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<float> linear = {0.f,   1.f,   0.5f, 0.0031308f, 0.002f, 0.18f,  //
                                     2.f,   -1.f,  nan,  inf,        -inf,   0.04f,  //
                                     0.75f, 1e-6f, 0.9f, 0.01f,      0.3f,   0.999f};
  const fs::path path = dir_ / "preview.png";
  write_png_preview(path, make_image(3, 2, linear));

  uint32_t width = 0, height = 0;
  const std::vector<uint8_t> pixels = read_png_rgb(path, width, height);
  ASSERT_EQ(width, 3u);
  ASSERT_EQ(height, 2u);
  ASSERT_EQ(pixels.size(), linear.size());
  // Hand-checked codes: 0.5 -> 0.7354 * 255 = 187.5 -> 188, 0.18 -> 117.6 -> 118, 0.002 (linear
  // segment) -> 0.02584 * 255 = 6.59 -> 7; out of range clamps; non-finite values give 0.
  EXPECT_EQ(pixels[0], 0);
  EXPECT_EQ(pixels[1], 255);
  EXPECT_EQ(pixels[2], 188);
  EXPECT_EQ(pixels[4], 7);
  EXPECT_EQ(pixels[5], 118);
  EXPECT_EQ(pixels[6], 255);
  EXPECT_EQ(pixels[7], 0);
  EXPECT_EQ(pixels[8], 0);
  EXPECT_EQ(pixels[9], 0);
  EXPECT_EQ(pixels[10], 0);
  for (size_t i = 0; i < linear.size(); ++i) {
    const int expected = std::isfinite(linear[i]) ? srgb8(linear[i]) : 0;
    EXPECT_EQ(int(pixels[i]), expected) << "linear " << linear[i];
  }
  EXPECT_EQ(list_dir(dir_), std::vector<std::string>{"preview.png"});
}

TEST_F(PngTest, AppliesExposureBeforeClamping) {
  const fs::path path = dir_ / "exposed.png";
  write_png_preview(path, make_image(2, 1, {0.25f, 0.09f, 0.6f, 0.001f, 1e38f, 0.f}), 2.f);
  uint32_t width = 0, height = 0;
  const std::vector<uint8_t> pixels = read_png_rgb(path, width, height);
  ASSERT_EQ(pixels.size(), 6u);
  EXPECT_EQ(pixels[0], 188);  // 0.25 * 2 = 0.5
  EXPECT_EQ(pixels[1], 118);  // 0.09 * 2 = 0.18
  EXPECT_EQ(pixels[2], 255);  // 1.2 clamps
  EXPECT_EQ(pixels[3], srgb8(0.002));
  EXPECT_EQ(pixels[4], 255);  // finite, overflows float when scaled, still clamps to 1
  EXPECT_EQ(pixels[5], 0);
}

TEST_F(PngTest, WriteIntoMissingDirectoryThrowsAndLeavesNoFile) {
  const fs::path path = dir_ / "missing" / "preview.png";
  const Image image = make_image(1, 1, {1, 2, 3});
  expect_image_error([&] { write_png_preview(path, image); }, {path.string()});
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(list_dir(dir_).empty());
}

TEST(MetricsTest, IdenticalImagesHaveZeroError) {
  const Image a = make_image(2, 1, {1.f, -0.f, 3.f, std::numeric_limits<float>::infinity(), 0, 1});
  const ImageDiff diff = compare_images(a, a);
  EXPECT_TRUE(diff.identical);
  EXPECT_EQ(diff.differing, 0u);
  EXPECT_EQ(diff.values, 6u);
  EXPECT_EQ(diff.rmse, 0.0);
  EXPECT_EQ(diff.rel_mse, 0.0);
  EXPECT_EQ(diff.mae, 0.0);
  EXPECT_EQ(diff.max_abs, 0.0);
}

TEST(MetricsTest, HandComputedDifferences) {
  // Differences 0, 0, 1 | 0, 0.5, 2 against reference values 4 (for 1), 1 (for 0.5), -2 (for 2).
  const Image test = make_image(2, 1, {1.f, 2.f, 3.f, 0.f, 1.5f, 0.f});
  const Image reference = make_image(2, 1, {1.f, 2.f, 4.f, 0.f, 1.f, -2.f});
  const ImageDiff diff = compare_images(test, reference);
  EXPECT_FALSE(diff.identical);
  EXPECT_EQ(diff.differing, 3u);
  EXPECT_DOUBLE_EQ(diff.rmse, std::sqrt((1.0 + 0.25 + 4.0) / 6));
  EXPECT_DOUBLE_EQ(diff.mae, (1.0 + 0.5 + 2.0) / 6);
  EXPECT_DOUBLE_EQ(diff.max_abs, 2.0);
  EXPECT_DOUBLE_EQ(diff.rel_mse, (1.0 / 16.01 + 0.25 / 1.01 + 4.0 / 4.01) / 6);
  EXPECT_EQ(diff.nan_values, 0u);
}

TEST(MetricsTest, TheReferenceIsTheSecondImage) {
  const Image a = make_image(1, 1, {2.f, 0.f, 0.f});
  const Image b = make_image(1, 1, {1.f, 0.f, 0.f});
  EXPECT_DOUBLE_EQ(compare_images(a, b).rel_mse, (1.0 / 1.01) / 3);
  EXPECT_DOUBLE_EQ(compare_images(b, a).rel_mse, (1.0 / 4.01) / 3);
}

TEST(MetricsTest, NegativeZeroDiffersInBitsOnly) {
  const ImageDiff diff =
      compare_images(make_image(1, 1, {-0.f, 1.f, 2.f}), make_image(1, 1, {0.f, 1.f, 2.f}));
  EXPECT_FALSE(diff.identical);
  EXPECT_EQ(diff.differing, 1u);
  EXPECT_EQ(diff.max_abs, 0.0);
  EXPECT_EQ(diff.rmse, 0.0);
}

TEST(MetricsTest, NanMakesMetricsInfiniteAndNeverIdentical) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const Image with_nan = make_image(2, 1, {nan, 1.f, 2.f, 3.f, 4.f, 5.f});
  const Image clean = make_image(2, 1, {0.f, 1.f, 2.f, 3.f, 4.f, 5.f});
  for (const ImageDiff& diff : {compare_images(with_nan, clean), compare_images(clean, with_nan),
                                compare_images(with_nan, with_nan)}) {
    EXPECT_FALSE(diff.identical);
    EXPECT_EQ(diff.differing, 1u);
    EXPECT_EQ(diff.nan_values, 1u);
    EXPECT_EQ(diff.max_abs, std::numeric_limits<double>::infinity());
    EXPECT_EQ(diff.rmse, std::numeric_limits<double>::infinity());
    EXPECT_EQ(diff.rel_mse, std::numeric_limits<double>::infinity());
    EXPECT_EQ(diff.mae, std::numeric_limits<double>::infinity());
  }
}

TEST(MetricsTest, DifferentInfinitiesAreInfinitelyFar) {
  const float inf = std::numeric_limits<float>::infinity();
  const ImageDiff diff =
      compare_images(make_image(1, 1, {inf, 0.f, 1.f}), make_image(1, 1, {-inf, 0.f, 1.f}));
  EXPECT_EQ(diff.differing, 1u);
  EXPECT_EQ(diff.nan_values, 0u);
  EXPECT_EQ(diff.max_abs, std::numeric_limits<double>::infinity());
  EXPECT_EQ(diff.rmse, std::numeric_limits<double>::infinity());
}

TEST(MetricsTest, SizeMismatchNamesBothSizes) {
  const Image a = make_image(3, 2, std::vector<float>(18));
  const Image b = make_image(2, 3, std::vector<float>(18));
  expect_image_error([&] { compare_images(a, b); }, {"3x2", "2x3"});
}

}  // namespace
}  // namespace rayfarm
