#include "common/image/film_output.h"

#include "common/image/error_estimate.h"
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
  // Beside the RGB, as layers that EXR viewers list: the variance of each pixel's mean
  // ("variance.R/G/B", +inf where a pixel has fewer than 2 samples) and its sample count
  // ("spp.Y"). Both are exact functions of the sums, so they are as deterministic as the RGB.
  const std::vector<float> variance = variance_rgb(film);
  const size_t pixels = size_t{film.width()} * film.height();
  const char* channel[3] = {"variance.R", "variance.G", "variance.B"};
  for (int c = 0; c < 3; ++c) {
    std::vector<float>& out = image.extra[channel[c]];
    out.resize(pixels);
    for (size_t p = 0; p < pixels; ++p) out[p] = variance[p * 3 + c];
  }
  std::vector<float>& spp = image.extra["spp.Y"];
  spp.assign(film.spp().begin(), film.spp().end());
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
