#pragma once
// Where a textured emitter emits. An emissive texture is mostly black on real models (a toy car's
// lamps, a bottle's label): a triangle whose texture coordinates reach only black texels emits
// nothing and is no light, and the others' powers follow the texels they cover, so that light
// selection spends its samples where the light is. Per emissive image texture, block sums of its
// texels (summed-area tables) answer each triangle in constant time.
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "common/image/texture_options.h"
#include "common/math/vec2.h"
#include "common/scene/scene.h"
#include "renderer/textures/texture_set.h"
#include "renderer/textures/uv_transform.h"

namespace rayfarm {

/// What the texels a lookup on one triangle can read hold.
struct TexelFootprint {
  /// Every such texel is zero (or negative, or NaN) in every channel: the emitted radiance,
  /// a product with the texture's positive part, is exactly zero on the whole triangle.
  bool black = false;
  /// The mean luminance of those texels (their positive parts, linear), at least the texels
  /// the triangle covers and a texel's width around them.
  double mean_luminance = 0.0;
};

class EmissionFootprints {
 public:
  EmissionFootprints() = default;
  /// Tables for the image textures that some material's emission reads.
  EmissionFootprints(const Scene& scene, const TextureSet& textures);

  /// For emission texture `texture` and a triangle of texture coordinates `uv`: a superset of
  /// the texels any lookup inside the triangle reads (its bounding box in the image, widened by
  /// the filter's reach and rounding, through the texture's transform and wrap modes). nullopt
  /// for a texture without a table (a checkerboard).
  std::optional<TexelFootprint> find(int32_t texture, const Vec2 (&uv)[3]) const;

 private:
  // Block sums over an image: cells of block x block texels, each with the number of its texels
  // that are not black and the sum of their luminances, as summed-area tables of (cw + 1) x
  // (ch + 1) entries (at most 2^20 cells: large images sum coarser blocks, still a superset).
  struct Table {
    uint32_t width = 0, height = 0, block = 1, cw = 0, ch = 0;
    ImageTextureOptions options;
    UvMap map;
    std::vector<uint64_t> count;
    std::vector<double> sum;
  };
  struct Sums {
    uint64_t count = 0;
    double sum = 0.0;
    double texels = 0.0;
  };
  static Table build(const TexelImage& image, const ImageTextureOptions& options);
  // Adds the texels of rows [y0, y1] x columns [x0, x1] (inclusive, inside the image).
  static void add_rect(const Table& t, int64_t x0, int64_t x1, int64_t y0, int64_t y1, Sums& out);

  std::map<int32_t, Table> tables_;
};

}  // namespace rayfarm
