#pragma once
// The textures of a scene: each (file, colour space) decoded once and shared by every texture
// that reads it, so a texture used by many materials costs its memory once. Materials hold
// indices into the set.
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "renderer/textures/checkerboard_texture.h"
#include "renderer/textures/image_texture.h"

namespace rayfarm {

using Texture = std::variant<ImageTexture, CheckerboardTexture>;

/// Built by one thread (load, add); read-only afterwards, when lookups from any number of
/// threads are safe.
class TextureSet {
 public:
  /// Returns the bytes of a file (from the scene's bundle).
  using ReadBytes = std::function<std::vector<uint8_t>()>;

  /// The index of the image decoded from `file` in `space`, decoding it (read() then
  /// decode_image, whose SceneError names `file`) only the first time this pair is asked for.
  uint32_t load_image(const std::string& file, ColourSpace space, const ReadBytes& read);
  /// A texture of image `image` (from load_image) with `options`; returns the texture's index.
  /// The same for an image already decoded (a scene's): its samples are copied the first time.
  uint32_t load_image(const std::string& file, ColourSpace space, const DecodedImage& decoded);
  uint32_t add_image_texture(uint32_t image, const ImageTextureOptions& options);
  uint32_t add_checkerboard(const CheckerboardTexture& checkerboard);

  const Texture& texture(uint32_t index) const { return textures_.at(index); }
  Vec4 eval(uint32_t index, float u, float v) const;
  /// The average of texture `index` over its image (every texel alike) or its period; computed
  /// on each call (a pass over the texels).
  Vec4 mean(uint32_t index) const;

  size_t image_count() const { return images_.size(); }
  size_t texture_count() const { return textures_.size(); }
  const std::shared_ptr<const TexelImage>& image(uint32_t index) const { return images_.at(index); }
  /// Bytes held by all the images' samples.
  size_t memory_bytes() const;

 private:
  std::map<std::pair<std::string, ColourSpace>, uint32_t> loaded_;
  std::vector<std::shared_ptr<const TexelImage>> images_;
  std::vector<Texture> textures_;
};

}  // namespace rayfarm
