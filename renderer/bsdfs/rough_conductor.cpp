#include "renderer/bsdfs/rough_conductor.h"

#include <cmath>

namespace rayfarm {

Vec3 RoughConductorBsdf::fresnel(float cos_i) const {
  const Vec3 f = m_.use_f0 ? fresnel_schlick(m_.f0, cos_i) : fresnel_conductor(cos_i, m_.eta, m_.k);
  return f * m_.specular_reflectance;
}

Vec3 RoughConductorBsdf::eval(const Vec3& wo_in, const Vec3& wi_in) const {
  if (facets_.is_smooth() || wo_in.z * wi_in.z <= 0.f) return Vec3(0.f);
  const bool flip = wo_in.z < 0.f;
  const Vec3 wo = to_upper(wo_in, flip), wi = to_upper(wi_in, flip);
  const Vec3 h = wo + wi;
  if (dot(h, h) == 0.f) return Vec3(0.f);
  const Vec3 wm = normalize(h);
  // D G F / (4 cos_o cos_i), times cos_i.
  return fresnel(dot(wo, wm)) * (facets_.d(wm) * facets_.g(wo, wi) / (4.f * wo.z));
}

float RoughConductorBsdf::pdf(const Vec3& wo_in, const Vec3& wi_in) const {
  if (facets_.is_smooth() || wo_in.z * wi_in.z <= 0.f) return 0.f;
  const bool flip = wo_in.z < 0.f;
  const Vec3 wo = to_upper(wo_in, flip), wi = to_upper(wi_in, flip);
  const Vec3 h = wo + wi;
  if (dot(h, h) == 0.f) return 0.f;
  const Vec3 wm = normalize(h);
  // The visible normals' density times the Jacobian of reflection, 1 / (4 wo.wm).
  const float c = dot(wo, wm);
  return c > 0.f ? facets_.visible_pdf(wo, wm) / (4.f * c) : 0.f;
}

bool RoughConductorBsdf::sample(const Vec3& wo_in, float /*u_lobe*/, float u1, float u2,
                                BsdfSample& out) const {
  if (wo_in.z == 0.f) return false;
  const bool flip = wo_in.z < 0.f;
  const Vec3 wo = to_upper(wo_in, flip);
  if (facets_.is_smooth()) {
    out.wi = to_upper(reflect_z(wo), flip);
    out.weight = fresnel(wo.z);
    out.pdf = 0.f;
    out.specular = true;
    return true;
  }
  const Vec3 wm = facets_.sample_visible(wo, u1, u2);
  const Vec3 wi = normalize(reflect_about(wo, wm));
  if (wi.z <= 0.f) return false;
  const float c = dot(wo, wm);
  const float pdf = c > 0.f ? facets_.visible_pdf(wo, wm) / (4.f * c) : 0.f;
  if (!(pdf > 0.f)) return false;
  // eval / pdf simplifies to F G / G1(wo), which stays finite where D and the pdf are huge.
  out.weight = fresnel(c) * (facets_.g(wo, wi) / facets_.g1(wo));
  out.wi = to_upper(wi, flip);
  out.pdf = pdf;
  out.specular = false;
  return true;
}

}  // namespace rayfarm
