#include "common/image/film_output.h"

#include "common/image/png.h"

namespace rayfarm {

Image film_to_image(const Film& film, const std::map<std::string, std::string>& attributes) {
  Image image;
  image.width = film.width();
  image.height = film.height();
  image.rgb = film.mean_rgb();
  image.attributes = attributes;
  image.attributes["rayfarm:spp"] = std::to_string(film.min_spp());
  image.attributes["rayfarm:nonfinite"] = std::to_string(film.nonfinite());
  return image;
}

std::filesystem::path preview_path(const std::filesystem::path& exr) {
  std::filesystem::path png = exr;
  png.replace_extension(".png");
  return png;
}

void write_film(const std::filesystem::path& exr, const Film& film,
                const std::map<std::string, std::string>& attributes) {
  const Image image = film_to_image(film, attributes);
  write_exr(exr, image);
  write_png_preview(preview_path(exr), image);
}

}  // namespace rayfarm
