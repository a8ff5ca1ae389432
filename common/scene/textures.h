#pragma once
// Textures as the scene describes them, and material parameters that are either a constant or a
// texture (docs/scene-format.md, "Textures"). The worker turns the descriptions into lookups
// (renderer/textures/).
#include <cassert>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <tuple>
#include <type_traits>

#include "common/image/decoded_image.h"
#include "common/image/texture_options.h"
#include "common/math/vec3.h"

namespace rayfarm {

/// One texture of the scene: an image file, or a procedural checkerboard.
struct TextureDesc {
  enum class Kind : uint8_t { kImage, kCheckerboard };
  std::string name;
  Kind kind = Kind::kImage;
  std::filesystem::path file;  ///< image: relative to the scene's folder
  ColourSpace space = ColourSpace::from_file;
  ImageTextureOptions options;  ///< image: filter, wrap, UV transform and origin
  /// The decoded file, shared by every texture of the same file; null when the scene was loaded
  /// only to be checked (the images were decoded, then dropped).
  std::shared_ptr<const DecodedImage> image;
  Vec3 color0{0.4f}, color1{0.2f};  ///< checkerboard colours (options.transform applies)
};

/// Which value of a texture a scalar parameter reads.
enum class TextureChannel : uint8_t { kR, kG, kB, kA, kMean };

/// A material parameter: a constant, or a texture's value times a constant factor.
template <class T>
struct Textured {
  T value{};             ///< the constant, or the factor applied to the texture's value
  int32_t texture = -1;  ///< index into Scene::textures, or -1
  TextureChannel channel = TextureChannel::kMean;  ///< scalar parameters: what they read

  Textured() = default;
  Textured(const T& v) : value(v) {}  // NOLINT(google-explicit-constructor): a constant is a T
  bool is_textured() const { return texture >= 0; }
  /// The constant. A textured parameter has none until resolve_textures() has looked it up:
  /// BSDFs read their parameters through this only after that.
  operator const T&() const {  // NOLINT(google-explicit-constructor): BSDFs read constants as T
    assert(texture < 0 && "a textured parameter read without its lookup");
    return value;
  }
};

using TexturedRgb = Textured<Vec3>;
using TexturedFloat = Textured<float>;

/// `params` with every textured parameter (those P::textured() lists) replaced by its value at
/// one surface point: `lookup.reflectance(rgb)` for colours, `lookup.number(x)` kept in [0, 1]
/// for numbers (every textured number of the format lies there).
template <class P, class Lookup>
P resolve_textures(const P& params, const Lookup& lookup) {
  P out = params;
  std::apply(
      [&](auto... field) {
        [[maybe_unused]] auto resolve = [&](auto& p) {
          if constexpr (std::is_same_v<std::decay_t<decltype(p)>, TexturedRgb>) {
            p = TexturedRgb(lookup.reflectance(p));
          } else {
            const float v = lookup.number(p);
            p = TexturedFloat(v >= 0.f ? (v <= 1.f ? v : 1.f) : 0.f);
          }
        };
        (resolve(out.*field), ...);
      },
      P::textured());
  return out;
}

}  // namespace rayfarm
