#include "renderer/textures/texture_set.h"

#include <cmath>
#include <span>

#include "common/image/decode_image.h"

namespace rayfarm {

uint32_t TextureSet::load_image(const std::string& file, ColourSpace space, const ReadBytes& read) {
  const auto key = std::pair{file, space};
  if (const auto it = loaded_.find(key); it != loaded_.end()) return it->second;
  const std::vector<uint8_t> bytes = read();
  auto image = std::make_shared<const TexelImage>(
      decode_image(std::span<const uint8_t>(bytes.data(), bytes.size()), file), space);
  const auto index = static_cast<uint32_t>(images_.size());
  images_.push_back(std::move(image));
  loaded_.emplace(key, index);
  return index;
}

uint32_t TextureSet::load_image(const std::string& file, ColourSpace space,
                                const DecodedImage& decoded) {
  const auto key = std::pair{file, space};
  if (const auto it = loaded_.find(key); it != loaded_.end()) return it->second;
  const auto index = static_cast<uint32_t>(images_.size());
  images_.push_back(std::make_shared<const TexelImage>(DecodedImage(decoded), space));
  loaded_.emplace(key, index);
  return index;
}

uint32_t TextureSet::add_image_texture(uint32_t image, const ImageTextureOptions& options) {
  textures_.emplace_back(ImageTexture(images_.at(image), options));
  return static_cast<uint32_t>(textures_.size() - 1);
}

uint32_t TextureSet::add_checkerboard(const CheckerboardTexture& checkerboard) {
  textures_.emplace_back(checkerboard);
  return static_cast<uint32_t>(textures_.size() - 1);
}

Vec4 TextureSet::eval(uint32_t index, float u, float v) const {
  return std::visit([&](const auto& texture) { return texture.eval(u, v); }, textures_[index]);
}

Vec4 TextureSet::mean(uint32_t index) const {
  if (const auto* checker = std::get_if<CheckerboardTexture>(&textures_.at(index)))
    return checker->mean();
  const TexelImage& image = std::get<ImageTexture>(textures_[index]).image();
  double sum[4] = {0.0, 0.0, 0.0, 0.0};
  for (uint32_t y = 0; y < image.height(); ++y) {
    for (uint32_t x = 0; x < image.width(); ++x) {
      const Vec4 t = image.texel(x, y);
      for (int c = 0; c < 4; ++c) sum[c] += std::isfinite(t[c]) ? t[c] : 0.0;
    }
  }
  const double n = double(image.width()) * image.height();
  return n > 0.0 ? Vec4(float(sum[0] / n), float(sum[1] / n), float(sum[2] / n), float(sum[3] / n))
                 : Vec4();
}

size_t TextureSet::memory_bytes() const {
  size_t total = 0;
  for (const auto& image : images_) total += image->memory_bytes();
  return total;
}

}  // namespace rayfarm
