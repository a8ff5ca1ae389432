#pragma once
// An emissive triangle, sampled uniformly by area.
#include <cmath>
#include <cstdint>
#include <optional>

#include "worker/lights/area_light.h"

namespace rayfarm {

class TriangleLight {
 public:
  /// The light of triangle `tri` of mesh `mesh`; nullopt when its material does not emit or it
  /// cannot be sampled (no area in float). An emitter left out keeps light index -1, and BSDF
  /// rays then count it fully.
  static std::optional<TriangleLight> make(const Scene& scene, uint32_t mesh, uint32_t tri,
                                           const EmissionTextures* tex = nullptr) {
    const TriangleMesh& m = scene.meshes[mesh];
    const Material& mat = scene.materials[m.materials[tri]];
    if (!mat.is_emissive()) return std::nullopt;
    const Vec3& a = m.positions[m.indices[3 * tri]];
    const Vec3& b = m.positions[m.indices[3 * tri + 1]];
    const Vec3& c = m.positions[m.indices[3 * tri + 2]];
    const double area = triangle_area(a, b, c);
    Vec3 n;
    if (!(area > 0.0) || area > 3e38 || !triangle_normal(a, b, c, n)) return std::nullopt;
    const double sides = mat.two_sided ? 2.0 : 1.0;
    TriangleLight light;
    light.v0_ = a, light.v1_ = b, light.v2_ = c, light.n_ = n;
    light.area_ = static_cast<float>(area);
    light.p_error_ = triangle_point_error(a, b, c);
    light.material_ = &mat;
    light.geom_ = mesh, light.prim_ = tri;
    light.power_ =
        double(luminance(power_radiance(mat, m.materials[tri], tex))) * area * kPi * sides;
    if (mat.emission.is_textured() && tex != nullptr) {
      // Texture coordinates as the hits on it have them: the mesh's, else the barycentrics.
      light.textures_ = tex->textures;
      if (!m.uvs.empty()) {
        for (int i = 0; i < 3; ++i) light.uv_[i] = m.uvs[m.indices[3 * tri + i]];
      } else {
        light.uv_[1] = {1.f, 0.f};
        light.uv_[2] = {0.f, 1.f};
      }
    }
    return light;
  }

  /// Emitted power (luminance); in double: luminance x area x pi overflows float for huge ones.
  double power() const { return power_; }
  /// The primitive that emits (mesh and triangle), for SceneData::set_light_index.
  uint32_t geom() const { return geom_; }
  uint32_t prim() const { return prim_; }

  /// A uniform point on the triangle as seen from `ref`; p_select: the selection probability.
  bool sample(const Vec3& ref, float p_select, float u1, float u2, LightSample& out) const {
    const float su = std::sqrt(u1);
    const float b0 = 1.f - su, b1 = u2 * su, b2 = 1.f - b0 - b1;
    const Vec3 p = v0_ * b0 + v1_ * b1 + v2_ * b2;
    const TextureLookup tex =
        textures_ ? TextureLookup(textures_, uv_[0] * b0 + uv_[1] * b1 + uv_[2] * b2)
                  : TextureLookup();
    return finish_area_sample(ref, p, n_, p_error_, area_, *material_, p_select, out, tex);
  }
  /// Density sample() has for reaching (p, n) from `ref`.
  float pdf(float p_select, const Vec3& ref, const Vec3& p, const Vec3& n) const {
    return area_light_pdf(p_select, area_, ref, p, n);
  }

 private:
  TriangleLight() = default;

  Vec3 v0_, v1_, v2_;
  Vec3 n_;  // unit normal, front side
  float area_ = 0.f, p_error_ = 0.f;
  const Material* material_ = nullptr;
  uint32_t geom_ = 0, prim_ = 0;
  double power_ = 0.0;
  const TextureSet* textures_ = nullptr;  // set for textured emission only
  Vec2 uv_[3];
};

}  // namespace rayfarm
