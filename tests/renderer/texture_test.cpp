// Texture lookups: filtering at and between texel centres, wrap modes, the UV origin and
// transform, the sRGB decode, the checkerboard's definition, and the shared images of a
// TextureSet.
#include <cmath>
#include <memory>
#include <numbers>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/scene/scene_files.h"
#include "tests/support/image_writers.h"
#include "renderer/textures/texture_set.h"

namespace rayfarm {
namespace {

/// A linear float image, RGBA: texel (x, y) = (x + 10 y, 2 x, 3 y, 0.5 + 0.1 x).
std::shared_ptr<const TexelImage> float_image(uint32_t width, uint32_t height) {
  DecodedImage image;
  image.width = width, image.height = height, image.channels = 4;
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      const auto fx = static_cast<float>(x), fy = static_cast<float>(y);
      for (float value : {fx + 10 * fy, 2 * fx, 3 * fy, 0.5f + 0.1f * fx}) {
        image.floats.push_back(value);
      }
    }
  }
  return std::make_shared<const TexelImage>(std::move(image), ColourSpace::from_file);
}

Vec4 expected_texel(uint32_t x, uint32_t y) {
  const auto fx = static_cast<float>(x), fy = static_cast<float>(y);
  return {fx + 10 * fy, 2 * fx, 3 * fy, 0.5f + 0.1f * fx};
}

void expect_near(const Vec4& got, const Vec4& want, float tolerance = 1e-5f) {
  for (int c = 0; c < 4; ++c) EXPECT_NEAR(got[c], want[c], tolerance) << "channel " << c;
}

ImageTexture texture(std::shared_ptr<const TexelImage> image, ImageTextureOptions options = {}) {
  return ImageTexture(std::move(image), options);
}

TEST(ImageTexture, BilinearAtTexelCentresReturnsTheTexel) {
  const auto image = float_image(4, 3);
  for (UvOrigin origin : {UvOrigin::bottom_left, UvOrigin::top_left}) {
    ImageTextureOptions options;
    options.origin = origin;
    const ImageTexture tex = texture(image, options);
    for (uint32_t y = 0; y < 3; ++y) {
      for (uint32_t x = 0; x < 4; ++x) {
        const float u = (x + 0.5f) / 4.f;
        const float t = (y + 0.5f) / 3.f;  // down from the top row
        const float v = origin == UvOrigin::bottom_left ? 1.f - t : t;
        SCOPED_TRACE("texel " + std::to_string(x) + ", " + std::to_string(y));
        expect_near(tex.eval(u, v), expected_texel(x, y));
      }
    }
  }
}

TEST(ImageTexture, BilinearHalfwayBetweenTexelsIsTheirMean) {
  const auto image = float_image(4, 3);
  ImageTextureOptions options;
  options.origin = UvOrigin::top_left;
  const ImageTexture tex = texture(image, options);
  auto mean = [](const Vec4& a, const Vec4& b) { return 0.5f * (a + b); };
  // Between (1, 1) and (2, 1), then between (2, 0) and (2, 1), then the four around (2, 1).
  expect_near(tex.eval(2.f / 4, 1.5f / 3), mean(expected_texel(1, 1), expected_texel(2, 1)));
  expect_near(tex.eval(2.5f / 4, 1.f / 3), mean(expected_texel(2, 0), expected_texel(2, 1)));
  expect_near(tex.eval(2.f / 4, 1.f / 3), mean(mean(expected_texel(1, 0), expected_texel(2, 0)),
                                               mean(expected_texel(1, 1), expected_texel(2, 1))));
}

TEST(ImageTexture, NearestReturnsTheTexelThePointFallsIn) {
  const auto image = float_image(4, 3);
  ImageTextureOptions options;
  options.origin = UvOrigin::top_left;
  options.filter = TextureFilter::nearest;
  const ImageTexture nearest = texture(image, options);
  options.filter = TextureFilter::bilinear;
  const ImageTexture bilinear = texture(image, options);
  // 0.3 of the way from texel 1's centre to texel 2's: nearest keeps texel 1 (x in [1, 2)).
  const float u = (1.5f + 0.3f) / 4, v = 1.5f / 3;
  expect_near(nearest.eval(u, v), expected_texel(1, 1));
  expect_near(bilinear.eval(u, v), 0.7f * expected_texel(1, 1) + 0.3f * expected_texel(2, 1));
  expect_near(nearest.eval(0.999f, 0.999f), expected_texel(3, 2));
  expect_near(nearest.eval(0.f, 0.f), expected_texel(0, 0));
}

TEST(ImageTexture, WrapModesOutsideTheUnitSquare) {
  const auto image = float_image(4, 1);
  struct Case {
    TextureWrap wrap;
    float u;
    uint32_t texel;
  };
  // With 4 texels, u = -0.25 falls in texel 3 when repeating (as 0.75), texel 1 when mirrored
  // (as 0.25), texel 0 when clamped; u = 1.25 in texels 1, 3 (as 0.75) and 3. The cases step
  // 0.1 to either side of those points, away from texel edges.
  const std::vector<Case> cases = {
      {TextureWrap::repeat, -0.25f + 0.1f, 3}, {TextureWrap::repeat, 1.25f + 0.1f, 1},
      {TextureWrap::mirror, -0.25f + 0.1f, 0}, {TextureWrap::mirror, 1.25f + 0.1f, 2},
      {TextureWrap::mirror, -0.25f - 0.1f, 1}, {TextureWrap::mirror, 1.25f - 0.1f, 3},
      {TextureWrap::clamp, -0.25f, 0},         {TextureWrap::clamp, 1.25f, 3},
      {TextureWrap::repeat, -7.9f, 0},         {TextureWrap::repeat, 1e9f + 0.5f, 0},
      {TextureWrap::mirror, 2.6f, 2},          {TextureWrap::mirror, 3.6f, 1},
  };
  for (const Case& c : cases) {
    ImageTextureOptions options;
    options.filter = TextureFilter::nearest;
    options.wrap_u = c.wrap;
    SCOPED_TRACE("wrap " + std::to_string(static_cast<int>(c.wrap)) + " u " + std::to_string(c.u));
    expect_near(texture(image, options).eval(c.u, 0.5f), expected_texel(c.texel, 0));
  }
  // Bilinear across the seam: at u = 0 repeat blends the last and first texels, clamp and
  // mirror give the first; at u = -0.25 (a texel centre of the neighbouring copy) the texel.
  ImageTextureOptions options;
  options.wrap_u = TextureWrap::repeat;
  expect_near(texture(image, options).eval(0.f, 0.5f),
              0.5f * (expected_texel(3, 0) + expected_texel(0, 0)));
  expect_near(texture(image, options).eval(-0.125f, 0.5f), expected_texel(3, 0));
  options.wrap_u = TextureWrap::clamp;
  expect_near(texture(image, options).eval(0.f, 0.5f), expected_texel(0, 0));
  expect_near(texture(image, options).eval(-0.25f, 0.5f), expected_texel(0, 0));
  options.wrap_u = TextureWrap::mirror;
  expect_near(texture(image, options).eval(0.f, 0.5f), expected_texel(0, 0));
  expect_near(texture(image, options).eval(-0.125f, 0.5f), expected_texel(0, 0));
  expect_near(texture(image, options).eval(-0.375f, 0.5f), expected_texel(1, 0));
  // Per axis: v wraps on its own.
  const auto tall = float_image(1, 4);
  options = {};
  options.filter = TextureFilter::nearest;
  options.origin = UvOrigin::top_left;
  options.wrap_u = TextureWrap::clamp;
  options.wrap_v = TextureWrap::mirror;
  expect_near(texture(tall, options).eval(5.f, -0.2f), expected_texel(0, 0));
  expect_near(texture(tall, options).eval(5.f, 1.2f), expected_texel(0, 3));
  // Non-finite coordinates read as 0.
  expect_near(texture(tall, options).eval(NAN, INFINITY), expected_texel(0, 0));
}

TEST(ImageTexture, UvOriginBottomLeftPutsVOneAtTheTopRow) {
  const auto image = float_image(1, 4);
  ImageTextureOptions options;
  options.filter = TextureFilter::nearest;
  expect_near(texture(image, options).eval(0.5f, 0.95f), expected_texel(0, 0));
  expect_near(texture(image, options).eval(0.5f, 0.05f), expected_texel(0, 3));
  options.origin = UvOrigin::top_left;
  expect_near(texture(image, options).eval(0.5f, 0.95f), expected_texel(0, 3));
  expect_near(texture(image, options).eval(0.5f, 0.05f), expected_texel(0, 0));
}

TEST(UvTransform, FollowsKhrTextureTransform) {
  // glTF's example: the lower-left quadrant of the image (top-left origin), turned clockwise.
  UvTransform t;
  t.offset = {0.f, 1.f};
  t.rotation = static_cast<float>(std::numbers::pi / 2);
  t.scale = {0.5f, 0.5f};
  const UvMap map(t);
  auto expect_maps = [&](double u, double v, double want_u, double want_v) {
    const auto [mu, mv] = map.apply(u, v);
    EXPECT_NEAR(mu, want_u, 1e-6) << u << ", " << v;
    EXPECT_NEAR(mv, want_v, 1e-6) << u << ", " << v;
  };
  expect_maps(0, 0, 0, 1);
  expect_maps(1, 0, 0, 0.5);
  expect_maps(0, 1, 0.5, 1);
  expect_maps(1, 1, 0.5, 0.5);
  // Scale before offset: offset is in the transformed units.
  t = {};
  t.offset = {0.25f, 0.f};
  t.scale = {2.f, 3.f};
  const UvMap scaled(t);
  const auto [su, sv] = scaled.apply(0.1, 0.2);
  EXPECT_NEAR(su, 0.45, 1e-6);
  EXPECT_NEAR(sv, 0.6, 1e-6);
  // Through a texture: an offset of a quarter moves the lookup one texel of four.
  const auto image = float_image(4, 1);
  ImageTextureOptions options;
  options.filter = TextureFilter::nearest;
  options.transform.offset = {0.25f, 0.f};
  expect_near(texture(image, options).eval(0.1f, 0.5f), expected_texel(1, 0));
}

TEST(ImageTexture, SrgbSamplesAreDecodedThroughTheFormula) {
  DecodedImage image;
  image.width = 256, image.height = 1, image.channels = 2;  // gray + alpha
  for (int i = 0; i < 256; ++i) image.bytes.insert(image.bytes.end(), {uint8_t(i), uint8_t(i)});
  image.display_encoded = true;
  DecodedImage copy = image;
  ImageTextureOptions options;
  options.filter = TextureFilter::nearest;
  const ImageTexture srgb(
      std::make_shared<const TexelImage>(std::move(image), ColourSpace::from_file), options);
  const ImageTexture linear(
      std::make_shared<const TexelImage>(std::move(copy), ColourSpace::linear), options);
  for (int i = 0; i < 256; ++i) {
    const double c = i / 255.0;
    const double want = c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
    const float u = (i + 0.5f) / 256.f;
    const Vec4 got = srgb.eval(u, 0.5f);
    EXPECT_NEAR(got.x, want, 1e-6 * want + 1e-9) << i;
    EXPECT_EQ(got.x, got.z);
    EXPECT_FLOAT_EQ(got.w, static_cast<float>(c)) << "alpha is never decoded";
    EXPECT_FLOAT_EQ(linear.eval(u, 0.5f).x, static_cast<float>(c)) << "linear override";
  }
  // Float samples marked sRGB (a 16-bit PNG) go through the same curve.
  DecodedImage wide;
  wide.width = 1, wide.height = 1, wide.channels = 3, wide.display_encoded = true;
  wide.floats = {0.5f, 0.02f, 1.f};
  const TexelImage wide_image(std::move(wide), ColourSpace::from_file);
  expect_near(wide_image.texel(0, 0), {srgb_to_linear(0.5f), 0.02f / 12.92f, 1.f, 1.f}, 1e-7f);
  EXPECT_NEAR(srgb_to_linear(0.5f), 0.21404114f, 1e-7f);
}

TEST(ImageTexture, ChannelsAndMono) {
  DecodedImage rgb;
  rgb.width = 1, rgb.height = 1, rgb.channels = 3, rgb.floats = {0.2f, 0.4f, 0.8f};
  const ImageTexture tex(std::make_shared<const TexelImage>(std::move(rgb), ColourSpace::linear),
                         {});
  EXPECT_FLOAT_EQ(tex.eval_channel(0.3f, 0.3f, 1), 0.4f);
  EXPECT_FLOAT_EQ(tex.eval_channel(0.3f, 0.3f, 3), 1.f);
  EXPECT_FLOAT_EQ(tex.eval_mono(0.3f, 0.3f), 0.2126f * 0.2f + 0.7152f * 0.4f + 0.0722f * 0.8f);
  DecodedImage gray;
  gray.width = 1, gray.height = 1, gray.channels = 1, gray.floats = {0.3f};
  const ImageTexture mono(std::make_shared<const TexelImage>(std::move(gray), ColourSpace::linear),
                          {});
  EXPECT_EQ(mono.eval_mono(0.7f, 0.1f), 0.3f);
  EXPECT_EQ(mono.eval(0.7f, 0.1f), Vec4(0.3f, 0.3f, 0.3f, 1.f));
  DecodedImage broken;
  broken.width = 2, broken.height = 1, broken.channels = 3, broken.floats = {1.f};
  EXPECT_THROW(TexelImage(std::move(broken), ColourSpace::linear), std::invalid_argument);
}

TEST(CheckerboardTexture, MatchesItsDefinition) {
  const Vec4 c0(1, 0, 0, 1), c1(0, 0, 1, 1);
  UvTransform t;
  t.scale = {4.f, 2.f};
  const CheckerboardTexture plain(c0, c1), scaled(c0, c1, t);
  auto definition = [&](double u, double v) {
    const bool a = u - std::floor(u) > 0.5, b = v - std::floor(v) > 0.5;
    return a != b ? c0 : c1;
  };
  int colour0 = 0;
  for (int i = -40; i <= 40; ++i) {
    for (int j = -40; j <= 40; ++j) {
      const float u = 0.0371f * i + 0.003f, v = 0.0413f * j + 0.001f;
      ASSERT_EQ(plain.eval(u, v), definition(u, v)) << u << ", " << v;
      ASSERT_EQ(scaled.eval(u, v), definition(4.0 * u, 2.0 * v)) << u << ", " << v;
      colour0 += plain.eval(u, v) == c0;
    }
  }
  EXPECT_NEAR(colour0 / (81.0 * 81.0), 0.5, 0.05);
  EXPECT_EQ(plain.eval(0.25f, 0.25f), c1);  // the origin's square is colour1
  EXPECT_EQ(plain.eval(0.75f, 0.25f), c0);
  EXPECT_EQ(plain.eval(0.75f, 0.75f), c1);
  EXPECT_EQ(plain.eval(0.5f, 0.75f), c0);  // 1/2 itself belongs to the lower half
}

TEST(TextureSet, DecodesEachFileAndColourSpaceOnce) {
  testing::PngSpec spec;
  spec.width = 2, spec.height = 2, spec.color_type = PNG_COLOR_TYPE_RGB;
  spec.samples = {0, 64, 128, 10, 20, 30, 255, 255, 255, 40, 50, 60};
  const testing::Bytes png = testing::encode_png(spec);
  int reads = 0;
  auto read = [&] {
    ++reads;
    return png;
  };
  TextureSet set;
  const uint32_t a = set.load_image("tex/a.png", ColourSpace::from_file, read);
  const uint32_t again = set.load_image("tex/a.png", ColourSpace::from_file, read);
  const uint32_t as_linear = set.load_image("tex/a.png", ColourSpace::linear, read);
  EXPECT_EQ(a, again);
  EXPECT_NE(a, as_linear);
  EXPECT_EQ(reads, 2);
  EXPECT_EQ(set.image_count(), 2u);
  EXPECT_EQ(set.memory_bytes(), 2u * 12u);  // 8-bit samples stay 8-bit
  EXPECT_TRUE(set.image(a)->srgb());
  EXPECT_FALSE(set.image(as_linear)->srgb());

  ImageTextureOptions nearest;
  nearest.filter = TextureFilter::nearest;
  const uint32_t t0 = set.add_image_texture(a, nearest);
  const uint32_t t1 = set.add_image_texture(a, {});
  const uint32_t t2 = set.add_checkerboard(CheckerboardTexture({1, 1, 1, 1}, {0, 0, 0, 1}));
  EXPECT_EQ(set.texture_count(), 3u);
  EXPECT_EQ(std::get<ImageTexture>(set.texture(t0)).shared_image().get(),
            std::get<ImageTexture>(set.texture(t1)).shared_image().get());
  // Bottom-left origin: (0.25, 0.25) is the bottom row's first pixel, (255, 255, 255).
  expect_near(set.eval(t0, 0.25f, 0.25f), {1.f, 1.f, 1.f, 1.f});
  EXPECT_EQ(set.eval(t2, 0.25f, 0.25f), Vec4(0, 0, 0, 1));

  // A broken file: the decoder's SceneError names it, and nothing is added.
  EXPECT_THROW(set.load_image("tex/bad.png", ColourSpace::from_file,
                              [] {
                                return testing::Bytes{1, 2, 3};
                              }),
               SceneError);
  EXPECT_EQ(set.image_count(), 2u);
}

TEST(TextureSet, ConcurrentLookupsMatchSequentialOnes) {
  TextureSet set;
  const uint32_t image = set.load_image("a.hdr", ColourSpace::from_file, [] {
    testing::Bytes rgbe;
    for (int i = 0; i < 16 * 16; ++i) {
      rgbe.insert(rgbe.end(),
                  {uint8_t(i), uint8_t(255 - i), uint8_t(i * 7), uint8_t(120 + i % 16)});
    }
    return testing::encode_hdr(rgbe, 16, 16, true);
  });
  const uint32_t tex = set.add_image_texture(image, {});
  auto lookups = [&] {
    std::vector<Vec4> out;
    for (int i = 0; i < 20000; ++i) out.push_back(set.eval(tex, 0.0137f * i, -0.0071f * i));
    return out;
  };
  const std::vector<Vec4> sequential = lookups();
  std::vector<std::vector<Vec4>> results(4);
  std::vector<std::thread> threads;
  for (auto& r : results) threads.emplace_back([&r, &lookups] { r = lookups(); });
  for (auto& t : threads) t.join();
  for (const auto& r : results) EXPECT_EQ(r, sequential);
}

}  // namespace
}  // namespace rayfarm
