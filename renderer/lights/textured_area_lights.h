#pragma once
// Emissive triangles and spheres whose emission is a texture: the plain lights' sampling, with
// the radiance read at the sampled point's texture coordinates (as a hit there has them). Kinds
// of their own, so that lights of constant emission carry no trace of textures.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "renderer/lights/sphere_light.h"
#include "renderer/lights/triangle_light.h"

namespace rayfarm {

class TexturedTriangleLight {
 public:
  /// The light of triangle `tri` of mesh `mesh` when its material's emission is textured.
  static std::optional<TexturedTriangleLight> make(const Scene& scene, uint32_t mesh, uint32_t tri,
                                                   const EmissionTextures& tex) {
    const TriangleMesh& m = scene.meshes[mesh];
    const Material& mat = scene.materials[m.materials[tri]];
    if (!mat.emission.is_textured()) return std::nullopt;
    // The mesh's texture coordinates, else the barycentrics (u, v) of corners 1 and 2.
    Vec2 uv[3] = {{0.f, 0.f}, {1.f, 0.f}, {0.f, 1.f}};
    if (!m.uvs.empty())
      for (int i = 0; i < 3; ++i) uv[i] = m.uvs[m.indices[3 * tri + i]];
    // A triangle whose texels are all black emits exactly nothing: no light (a BSDF ray that
    // finds it adds zero either way). The others weigh what their own texels emit.
    std::optional<TexelFootprint> footprint;
    if (tex.footprints != nullptr) footprint = tex.footprints->find(mat.emission.texture, uv);
    if (footprint && footprint->black) return std::nullopt;
    auto base = TriangleLight::make(scene, mesh, tri, &tex);
    if (!base) return std::nullopt;
    if (footprint) {
      // Any emission keeps a share of the selection, however dim its texels read.
      const double mean = std::max(footprint->mean_luminance, 1e-9);
      base->set_power_luminance(double(luminance(mat.emission.value)) * mean);
    }
    TexturedTriangleLight light(*base, tex.textures, mat.emission);
    for (int i = 0; i < 3; ++i) light.uv_[i] = uv[i];
    return light;
  }

  double power() const { return base_.power(); }
  LightBounds bounds() const { return base_.bounds(); }
  uint32_t geom() const { return base_.geom(); }
  uint32_t prim() const { return base_.prim(); }
  bool sample(const Vec3& ref, float p_select, float u1, float u2, LightSample& out) const {
    return base_.sample_with(ref, p_select, u1, u2, out, [this](float b0, float b1, float b2) {
      return TextureLookup(textures_, uv_[0] * b0 + uv_[1] * b1 + uv_[2] * b2).radiance(emission_);
    });
  }
  float pdf(float p_select, const Vec3& ref, const Vec3& p, const Vec3& n) const {
    return base_.pdf(p_select, ref, p, n);
  }

 private:
  TexturedTriangleLight(const TriangleLight& base, const TextureSet* textures,
                        const TexturedRgb& emission)
      : base_(base), textures_(textures), emission_(emission) {}

  TriangleLight base_;
  const TextureSet* textures_;
  TexturedRgb emission_;
  Vec2 uv_[3];
};

class TexturedSphereLight {
 public:
  /// The light of sphere `index` when its material's emission is textured.
  static std::optional<TexturedSphereLight> make(const Scene& scene, uint32_t index,
                                                 const EmissionTextures& tex) {
    const Sphere& s = scene.spheres[index];
    const Material& mat = scene.materials[s.material];
    if (!mat.emission.is_textured()) return std::nullopt;
    auto base = SphereLight::make(scene, index, &tex);
    if (!base) return std::nullopt;
    return TexturedSphereLight(*base, tex.textures, mat.emission, s);
  }

  double power() const { return base_.power(); }
  LightBounds bounds() const { return base_.bounds(); }
  uint32_t geom() const { return base_.geom(); }
  uint32_t prim() const { return base_.prim(); }
  bool sample(const Vec3& ref, float p_select, float u1, float u2, LightSample& out) const {
    return base_.sample_with(ref, p_select, u1, u2, out, [this](const Vec3& n) {
      // The same angles as a hit's (SceneData::sphere_uv).
      float phi = std::atan2(dot(n, axes_[1]), dot(n, axes_[0]));
      if (phi < 0.f) phi += 2.f * kPi;
      const float theta = std::acos(std::clamp(dot(n, axes_[2]), -1.f, 1.f));
      return TextureLookup(textures_, {phi * (0.5f * kInvPi), theta * kInvPi}).radiance(emission_);
    });
  }
  float pdf(float p_select, const Vec3& ref, const Vec3& p, const Vec3& n) const {
    return base_.pdf(p_select, ref, p, n);
  }

 private:
  TexturedSphereLight(const SphereLight& base, const TextureSet* textures,
                      const TexturedRgb& emission, const Sphere& s)
      : base_(base),
        textures_(textures),
        emission_(emission),
        axes_{s.axis_x, s.axis_y, s.axis_z} {}

  SphereLight base_;
  const TextureSet* textures_;
  TexturedRgb emission_;
  Vec3 axes_[3];
};

}  // namespace rayfarm
