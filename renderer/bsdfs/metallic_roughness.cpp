#include "renderer/bsdfs/metallic_roughness.h"

#include <algorithm>
#include <cmath>

namespace rayfarm {
namespace {

float schlick_weight(float cos_i) {
  const float m = std::clamp(1.f - cos_i, 0.f, 1.f);
  return (m * m) * (m * m) * m;
}

/// The lower-side direction mirrored to the upper side: thin-walled transmission is the reflected
/// lobe's mirror image.
Vec3 mirror_z(const Vec3& w) { return {w.x, w.y, -w.z}; }

}  // namespace

MetallicRoughnessBsdf::MetallicRoughnessBsdf(const MetallicRoughnessMaterial& m)
    : m_(m), ggx_(m.roughness * m.roughness, m.roughness * m.roughness) {
  const float r = (m.ior - 1.f) / (m.ior + 1.f);
  f0_ = std::isfinite(r) ? r * r : 1.f;
  const float base = (1.f - m.metallic) * luminance(m.base_color);
  diffuse_share_ = base * (1.f - m.transmission);
  trans_share_ = base * m.transmission;
}

Vec3 MetallicRoughnessBsdf::specular_fresnel(float v_dot_h) const {
  const float w = schlick_weight(v_dot_h);
  const Vec3 metal = m_.base_color + (Vec3(1.f) - m_.base_color) * w;
  const float dielectric = f0_ + (1.f - f0_) * w;
  return metal * m_.metallic + Vec3(dielectric * (1.f - m_.metallic));
}

float MetallicRoughnessBsdf::schlick(float cos_i) const {
  return f0_ + (1.f - f0_) * schlick_weight(cos_i);
}

float MetallicRoughnessBsdf::dielectric_fresnel(float v_dot_h) const {
  return (1.f - m_.metallic) * (1.f - schlick(v_dot_h));
}

MetallicRoughnessBsdf::Lobes MetallicRoughnessBsdf::lobes(float cos_o) const {
  // Each lobe's albedo estimated by the Fresnel terms at wo. Floors keep every density positive
  // wherever its lobe can carry light: a black metal still reflects at grazing VdotH, and a rough
  // layer still transmits at grazing wo through micro-facets that face it.
  const float spec = std::max(luminance(specular_fresnel(cos_o)), 1e-2f);
  const float under = std::max(1.f - schlick(cos_o), 0.1f * (1.f - f0_));
  const float diffuse = diffuse_share_ * under, trans = trans_share_ * under;
  const float total = spec + diffuse + trans;
  return {spec / total, diffuse / total, trans / total};
}

Vec3 MetallicRoughnessBsdf::eval_upper(const Vec3& wo, const Vec3& wi) const {
  if (wi.z > 0.f) {
    // The diffuse base under the layer: weighted by the layer's Fresnel at wo and at wi, not at
    // the half vector as the specification writes fresnel_mix. The half vector is no direction
    // the diffuse light takes, and with it a white surface returned up to 1.85 times the light
    // it received at grazing incidence; the product of the two is reciprocal and conserves energy.
    const float base = dielectric_fresnel(wo.z) * (1.f - schlick(wi.z)) * (1.f - m_.transmission);
    Vec3 f = m_.base_color * (base * kInvPi * wi.z);
    if (!ggx_.is_smooth()) {
      const Vec3 h = normalize(wo + wi);
      const float vh = std::max(0.f, dot(wo, h));
      f += specular_fresnel(vh) * (ggx_.d(h) * ggx_.g(wo, wi) / (4.f * wo.z));
    }
    return f;
  }
  if (ggx_.is_smooth() || !(m_.transmission > 0.f)) return Vec3(0.f);
  const Vec3 wr = mirror_z(wi);
  const Vec3 h = normalize(wo + wr);
  const float vh = std::max(0.f, dot(wo, h));
  return m_.base_color *
         (m_.transmission * dielectric_fresnel(vh) * ggx_.d(h) * ggx_.g(wo, wr) / (4.f * wo.z));
}

float MetallicRoughnessBsdf::pdf_upper(const Vec3& wo, const Vec3& wi) const {
  const Lobes p = lobes(wo.z);
  const bool reflect = wi.z > 0.f;
  float pdf = reflect ? p.diffuse * wi.z * kInvPi : 0.f;
  if (ggx_.is_smooth()) return pdf;
  const Vec3 wr = reflect ? wi : mirror_z(wi);
  const Vec3 h = normalize(wo + wr);
  const float c = dot(wo, h);
  if (c > 0.f) pdf += (reflect ? p.spec : p.trans) * ggx_.visible_pdf(wo, h) / (4.f * c);
  return pdf;
}

Vec3 MetallicRoughnessBsdf::eval(const Vec3& wo, const Vec3& wi) const {
  if (wo.z == 0.f || wi.z == 0.f) return Vec3(0.f);
  const bool flip = wo.z < 0.f;
  return eval_upper(to_upper(wo, flip), to_upper(wi, flip));
}

float MetallicRoughnessBsdf::pdf(const Vec3& wo, const Vec3& wi) const {
  if (wo.z == 0.f || wi.z == 0.f) return 0.f;
  const bool flip = wo.z < 0.f;
  return pdf_upper(to_upper(wo, flip), to_upper(wi, flip));
}

bool MetallicRoughnessBsdf::sample(const Vec3& wo_in, float u_lobe, float u1, float u2,
                                   BsdfSample& out) const {
  if (wo_in.z == 0.f) return false;
  const bool flip = wo_in.z < 0.f;
  const Vec3 wo = to_upper(wo_in, flip);
  const Lobes p = lobes(wo.z);
  const bool spec = u_lobe < p.spec, trans = !spec && u_lobe >= p.spec + p.diffuse;
  if ((spec || trans) && ggx_.is_smooth()) {
    // The Dirac lobes: mirror reflection, or straight through the thin wall.
    out.wi = to_upper(spec ? reflect_z(wo) : -wo, flip);
    out.weight = spec ? specular_fresnel(wo.z) / p.spec
                      : m_.base_color * (m_.transmission * dielectric_fresnel(wo.z) / p.trans);
    out.pdf = 0.f;
    out.specular = true;
    return true;
  }
  Vec3 wi = spec || trans ? normalize(reflect_about(wo, ggx_.sample_visible(wo, u1, u2)))
                          : sample_cosine_hemisphere(u1, u2);
  if (wi.z <= 0.f) return false;
  if (trans) wi = mirror_z(wi);
  out.pdf = pdf_upper(wo, wi);
  if (!(out.pdf > 0.f)) return false;
  out.weight = eval_upper(wo, wi) / out.pdf;
  out.wi = to_upper(wi, flip);
  out.specular = false;
  return true;
}

}  // namespace rayfarm
