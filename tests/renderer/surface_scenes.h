#pragma once
// Scenes for the surface features (normal and bump maps, cut-outs, textured emission), written
// in the scene format so that the parser's part is tested with the renderer's.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "common/image/fixed.h"
#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"
#include "renderer/renderer.h"

namespace rayfarm::testing {

/// A scene file in `dir` with the given sections (JSON members without the braces).
inline Scene scene_from(TempDir& dir, const std::string& members) {
  return load_scene(dir.write("scene.json", "{" + members + "}"));
}

/// An orthographic camera on +z looking at the origin, seeing [-1, 1]^2 of the z = 0 plane on an
/// 8x8 film: the image's right is +x and its top +y, each pixel a 0.25 square.
inline const char* kTopView = R"(
    "camera": {"type": "orthographic", "eye": [0, 0, 5], "look_at": [0, 0, 0],
               "view_height": 2},
    "film": {"width": 8, "height": 8})";

/// The unit square [-1, 1]^2 at z, facing +z; u along +x, v along +y.
inline std::string quad_at(float z, const std::string& material) {
  return R"({"type": "quad", "corner": [-1, -1, )" + std::to_string(z) +
         R"(], "edge1": [2, 0, 0], "edge2": [0, 2, 0], "material": ")" + material + "\"}";
}

/// Each pixel's mean over `spp` samples, RGB, row-major, and the per-pixel sums of squares.
struct PixelMeans {
  std::vector<Vec3> mean;
  double total = 0.0, total_sq = 0.0;  ///< over every sample, red channel
  double samples = 0.0;

  double image_mean() const { return total / samples; }
  /// Standard error of image_mean().
  double standard_error() const {
    const double m = image_mean();
    return std::sqrt(std::max(0.0, total_sq / samples - m * m) / (samples - 1.0));
  }
};

inline PixelMeans render_pixels(const Scene& scene, uint32_t spp, IntegratorType integrator,
                                uint64_t seed = 1) {
  RenderSettings settings = scene.render;
  settings.spp = spp;
  settings.integrator = integrator;
  settings.seed = seed;
  settings.sampler = SamplerType::kIndependent;  // standard_error() needs independent samples
  Renderer renderer(scene, settings);
  const TileResult r = renderer.render({0, 0, scene.film.width, scene.film.height}, {0, spp});
  PixelMeans out;
  for (size_t p = 0; p < r.rect.pixel_count(); ++p) {
    out.mean.push_back(Vec3(float(from_fixed(r.sum[3 * p])), float(from_fixed(r.sum[3 * p + 1])),
                            float(from_fixed(r.sum[3 * p + 2]))) /
                       float(spp));
    out.total += from_fixed(r.sum[3 * p]);
    out.total_sq += from_fixed(r.sum_sq[3 * p]);
  }
  out.samples = double(r.rect.pixel_count()) * spp;
  return out;
}

}  // namespace rayfarm::testing
