#pragma once
// Normalised Phong: a diffuse lobe and a glossy lobe around the mirror direction, on both sides
// (mirrored to wo's side). sample() picks a lobe by the ratio of their luminances.
#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"

namespace rayfarm {

class PhongBsdf {
 public:
  using Params = PhongMaterial;
  /// Light arrives only from wo's side: light selection may leave out lights behind it.
  static constexpr bool kReflectsOnly = true;
  bool is_specular() const { return false; }

  explicit PhongBsdf(const PhongMaterial& m) : m_(m) {}

  /// f(wo, wi) * |cos(wi)|.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const;
  /// Solid-angle density with which sample() draws wi given wo.
  float pdf(const Vec3& wo, const Vec3& wi) const;
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const;

 private:
  PhongMaterial m_;
};

}  // namespace rayfarm
