#pragma once
// Textures as the scene describes them, and material parameters that are either a constant or a
// texture (docs/scene-format.md, "Textures"). The worker turns the descriptions into lookups
// (worker/textures/).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

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
};

using TexturedRgb = Textured<Vec3>;
using TexturedFloat = Textured<float>;

}  // namespace rayfarm
