#include "renderer/bsdfs/plastic.h"

#include <cmath>

#include "renderer/bsdfs/dielectric.h"
#include "renderer/bsdfs/gauss_legendre.h"

namespace rayfarm {
namespace {

/// 2 * integral over [0, 1] of F(c, eta) c dc: smooth in c when eta >= 1 (no total internal
/// reflection), where 32 Gauss-Legendre nodes are exact to float precision.
double diffuse_fresnel(double eta) {
  static const GaussLegendre<32> rule;
  double sum = 0.0;
  for (int i = 0; i < 32; ++i) {
    float cos_t = 0.f;
    sum += rule.w[i] * fresnel_dielectric(float(rule.x[i]), float(eta), cos_t) * rule.x[i];
  }
  return 2.0 * sum;
}

}  // namespace

float internal_diffuse_reflectance(float ior) {
  // From inside a denser medium the integrand has a kink at the critical angle; the light that
  // escapes is that of the outside average, scaled by the solid angle's compression 1 / ior^2.
  if (ior >= 1.f) return float(1.0 - (1.0 - diffuse_fresnel(ior)) / (double(ior) * ior));
  return float(diffuse_fresnel(1.0 / ior));
}

PlasticBsdf::PlasticBsdf(const PlasticMaterial& m)
    : ior_(m.ior),
      facets_(m.distribution, m.alpha, m.alpha),
      base_weight_(luminance(m.diffuse_reflectance)) {
  float internal = 0.f;
  if (facets_.is_smooth()) {
    // Constructed at every path vertex: the one integral is remembered per thread for the last
    // index asked, which in most scenes is the only one.
    thread_local float last_ior = -1.f, last_fdr = 0.f;
    if (m.ior != last_ior) {
      last_fdr = internal_diffuse_reflectance(m.ior);
      last_ior = m.ior;
    }
    internal = last_fdr;
  } else {
    const RoughCoatTable& table =
        m.coat_table ? *m.coat_table : unprepared_rough_coat(m.ior, m.distribution, m.alpha);
    coat_ = table.at(m.alpha);
    internal = coat_.internal;
  }
  const Vec3& rho = m.diffuse_reflectance;
  const Vec3 denom = m.nonlinear ? Vec3(1.f) - rho * internal : Vec3(1.f - internal);
  const float scale = kInvPi / (m.ior * m.ior);
  diffuse_ = rho * scale / denom;
  for (int c = 0; c < 3; ++c) {
    // ior 0+ reflects everything back inside, and its 1 / ior^2 overflows: no light reaches
    // the base then (T is 0), so the base adds nothing.
    if (!(denom[c] > 0.f) || !std::isfinite(diffuse_[c])) diffuse_ = Vec3(0.f);
  }
}

float PlasticBsdf::fresnel(float cos_i) const {
  float cos_t = 0.f;
  return fresnel_dielectric(cos_i, ior_, cos_t);
}

float PlasticBsdf::coat_probability(float reflected_o, float transmitted_o) const {
  const float coat = reflected_o, base = transmitted_o * base_weight_;
  return coat + base > 0.f ? coat / (coat + base) : 1.f;
}

Vec3 PlasticBsdf::eval_upper(const Vec3& wo, const Vec3& wi) const {
  Vec3 f = diffuse_ * (transmittance(wi.z) * transmittance(wo.z) * wi.z);
  if (!facets_.is_smooth()) {
    const Vec3 wm = normalize(wo + wi);
    // Masking and shadowing uncorrelated, G1(wo) G1(wi): the lobe whose albedo is the R that
    // the coat's tables integrate over the visible normals (rough_coat.h), so that T + R <= 1.
    const float g = facets_.g1(wo) * facets_.g1(wi);
    f += Vec3(facets_.d(wm) * g * fresnel(dot(wo, wm)) / (4.f * wo.z));
  }
  return f;
}

float PlasticBsdf::pdf_upper(const Vec3& wo, const Vec3& wi) const {
  float r_o = 0.f, t_o = 0.f;
  shares(wo.z, r_o, t_o);
  const float p_coat = coat_probability(r_o, t_o);
  float pdf = (1.f - p_coat) * wi.z * kInvPi;
  if (!facets_.is_smooth()) {
    const Vec3 wm = normalize(wo + wi);
    const float c = dot(wo, wm);
    if (c > 0.f) pdf += p_coat * facets_.visible_pdf(wo, wm) / (4.f * c);
  }
  return pdf;
}

Vec3 PlasticBsdf::eval(const Vec3& wo, const Vec3& wi) const {
  if (wo.z * wi.z <= 0.f) return Vec3(0.f);
  const bool flip = wo.z < 0.f;
  return eval_upper(to_upper(wo, flip), to_upper(wi, flip));
}

float PlasticBsdf::pdf(const Vec3& wo, const Vec3& wi) const {
  if (wo.z * wi.z <= 0.f) return 0.f;
  const bool flip = wo.z < 0.f;
  return pdf_upper(to_upper(wo, flip), to_upper(wi, flip));
}

bool PlasticBsdf::sample(const Vec3& wo_in, float u_lobe, float u1, float u2,
                         BsdfSample& out) const {
  if (wo_in.z == 0.f) return false;
  const bool flip = wo_in.z < 0.f;
  const Vec3 wo = to_upper(wo_in, flip);
  float r_o = 0.f, t_o = 0.f;
  shares(wo.z, r_o, t_o);
  const float p_coat = coat_probability(r_o, t_o);
  Vec3 wi;
  if (u_lobe < p_coat) {
    if (facets_.is_smooth()) {
      out.wi = to_upper(reflect_z(wo), flip);
      out.weight = Vec3(r_o / p_coat);
      out.pdf = 0.f;
      out.specular = true;
      return true;
    }
    wi = normalize(reflect_about(wo, facets_.sample_visible(wo, u1, u2)));
  } else {
    wi = sample_cosine_hemisphere(u1, u2);
  }
  if (wi.z <= 0.f) return false;
  out.pdf = pdf_upper(wo, wi);
  if (!(out.pdf > 0.f)) return false;
  out.weight = eval_upper(wo, wi) / out.pdf;
  out.wi = to_upper(wi, flip);
  out.specular = false;
  return true;
}

}  // namespace rayfarm
