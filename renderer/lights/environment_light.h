#pragma once
// Light from every direction at infinity: an equirectangular image, or a constant radiance,
// importance-sampled by luminance times sin(theta) with a piecewise-constant 2D distribution
// over the image's texels (rows by their total, then a column within the row). Lookups take the
// nearest texel, the same cell whose density the sampler uses, so that eval and pdf agree
// exactly and MIS sees one consistent estimator. A map read bilinearly (EnvironmentMap::bilinear)
// weighs each cell by the brightest texel its interpolation reads, so that the density is
// positive wherever the radiance is.
//
// Orientation (docs/scene-format.md, "Lights"), in the map's own frame before its rotation: the
// top row looks up (+y), the bottom row down; u runs from -z (u = 0) through +x (u = 1/4), +z
// (u = 1/2, the image's centre) and -x (u = 3/4).
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "common/math/vec3.h"
#include "renderer/lights/light_sample.h"

namespace rayfarm {

class EnvironmentLight {
 public:
  /// The scene's environment; nullopt when it has none, or it emits nothing. `scene_radius`:
  /// radius of a sphere holding the scene's geometry, for the power.
  static std::optional<EnvironmentLight> make(const Scene& scene, double scene_radius);

  /// Power for light selection: what the environment sends through the scene's bounding disc
  /// from every direction, pi r^2 times the integral of luminance over the sphere.
  double power() const { return power_; }
  /// The same radiance from every direction (a "constant" light): BSDF sampling draws it
  /// exactly as well as it draws anything, so light sampling leaves it out (light_set.h).
  bool constant() const { return constant_; }
  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }

  /// Radiance arriving along the unit direction `dir` (from the scene towards the sky).
  Vec3 eval(const Vec3& dir) const;
  /// Solid-angle density with which sample() draws the unit direction `dir`, before selection.
  float pdf_direction(const Vec3& dir) const;

  /// A direction drawn by the map's luminance; pdf includes the selection probability.
  bool sample(const Vec3& ref, float p_select, float u1, float u2, LightSample& out) const;
  /// No surface of the scene is the environment: emitters hit never ask it.
  float pdf(float /*p_select*/, const Vec3& /*ref*/, const Vec3& /*p*/, const Vec3& /*n*/) const {
    return 0.f;
  }

  /// The map's direction at image coordinates (u, v) in [0, 1]^2, in world space.
  Vec3 direction(float u, float v) const;
  /// The image coordinates of the unit world direction `dir`.
  std::array<float, 2> uv(const Vec3& dir) const;

 private:
  EnvironmentLight() = default;

  /// The texel (column, row) that image coordinates (u, v) fall in.
  uint32_t cell(float u, float v) const;
  /// Density over the image's (u, v) of the cell `index`.
  float pdf_uv(uint32_t index) const;

  uint32_t width_ = 0, height_ = 0;
  std::vector<Vec3> radiance_;       // texel times scale, row-major, top row first
  std::vector<float> weight_;        // luminance x sin(theta) per texel
  std::vector<double> row_cdf_;      // height_ + 1 entries, normalised
  std::vector<double> column_cdf_;   // (width_ + 1) per row, each normalised
  double total_weight_ = 0.0;        // sum of weight_
  std::array<float, 9> to_world_{};  // row-major rotation, world from map
  double power_ = 0.0;
  bool bilinear_ = false;  // EnvironmentMap::bilinear
  bool constant_ = false;
};

}  // namespace rayfarm
