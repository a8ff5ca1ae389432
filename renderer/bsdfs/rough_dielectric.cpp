#include "renderer/bsdfs/rough_dielectric.h"

#include <cmath>

namespace rayfarm {
namespace {

/// |ior - 1| below this is an index-matched interface: the transmission lobe's width is
/// proportional to |ior - 1|, and below this its peak exceeds what floats carry.
constexpr float kMatchedIndex = 1e-4f;

}  // namespace

RoughDielectricBsdf::RoughDielectricBsdf(const RoughDielectricMaterial& m)
    : ior_(m.ior),
      tint_(m.tint),
      facets_(m.distribution, m.alpha_u, m.alpha_v),
      index_matched_(std::fabs(m.ior - 1.f) < kMatchedIndex),
      smooth_(DielectricMaterial{m.ior, m.tint}) {}

bool RoughDielectricBsdf::half_vector(const Vec3& wo, const Vec3& wi, Half& h) const {
  if (wo.z == 0.f || wi.z == 0.f) return false;
  const bool reflect = wo.z * wi.z > 0.f;
  const float eta_o = wo.z > 0.f ? 1.f : ior_, eta_i = wi.z > 0.f ? 1.f : ior_;
  // The generalised half vector: n_o wo + n_i wi is normal to the micro-facet that refracts one
  // into the other (for reflection, wo + wi). In double: for refraction the two terms nearly
  // cancel, and the Jacobian's root eta wi.m + wo.m cancels again, so in float reciprocity
  // failed by 1% in the tails. The ratio of indices too: rounded to float, it tilts the half
  // vector by 1e-8, which moved a micro-facet cosine of 1e-5 (light refracted along the facet)
  // by 0.2% between wo -> wi and wi -> wo.
  const double e = reflect ? 1.0 : double(eta_i) / double(eta_o);
  h.eta = float(e);
  double mx = wo.x + e * wi.x, my = wo.y + e * wi.y, mz = wo.z + e * wi.z;
  const double len = std::sqrt(mx * mx + my * my + mz * mz);
  if (!(len > 0.0)) return false;
  const double s = mz < 0.0 ? -1.0 / len : 1.0 / len;
  mx *= s, my *= s, mz *= s;
  if (mz == 0.0) return false;
  const double co = wo.x * mx + wo.y * my + wo.z * mz;
  const double ci = wi.x * mx + wi.y * my + wi.z * mz;
  // The micro-facet must face wo and wi from their own sides.
  if (co * wo.z <= 0.0 || ci * wi.z <= 0.0) return false;
  if (!reflect && co * ci >= 0.0) return false;
  // F from the rarer side's cosine: from the denser side, cos_t = sqrt(1 - n^2 sin^2) loses all
  // its digits near the critical angle (1 - F was off by a factor 2 for micro-facets met at
  // grazing incidence), and one side for both orders keeps eval reciprocal.
  float cos_t = 0.f;
  if (reflect) {
    h.fresnel = fresnel_dielectric(float(std::fabs(co)), wo.z > 0.f ? ior_ : 1.f / ior_, cos_t);
  } else {
    const bool wo_rarer = eta_o < eta_i;
    h.fresnel = fresnel_dielectric(float(std::fabs(wo_rarer ? co : ci)),
                                   wo_rarer ? eta_i / eta_o : eta_o / eta_i, cos_t);
  }
  h.wm = Vec3{float(mx), float(my), float(mz)};
  h.co = float(co);
  h.ci = float(ci);
  h.denom = float(e * ci + co);
  return true;
}

Vec3 RoughDielectricBsdf::eval(const Vec3& wo, const Vec3& wi) const {
  if (is_specular()) return Vec3(0.f);
  Half h;
  if (!half_vector(wo, wi, h)) return Vec3(0.f);
  const float d = facets_.d(h.wm), g = facets_.g(wo, wi);
  const float cos_o = std::fabs(wo.z);
  if (wo.z * wi.z > 0.f) return Vec3(d * g * h.fresnel / (4.f * cos_o));
  // Walter's BTDF with the radiance factor: |wi.m| |wo.m| D G (1 - F) / (cos_o (wi.m + wo.m /
  // eta)^2 eta^2), times |cos_i| already cancelled. Written over (eta wi.m + wo.m)^2 so that the
  // eta^2 cancels.
  const float f = std::fabs(h.ci * h.co) * d * g * (1.f - h.fresnel) / (cos_o * h.denom * h.denom);
  return tint_ * f;
}

float RoughDielectricBsdf::pdf(const Vec3& wo, const Vec3& wi) const {
  if (is_specular()) return 0.f;
  Half h;
  if (!half_vector(wo, wi, h)) return 0.f;
  // Micro-normals are drawn as seen from wo mirrored to the upper side (D is symmetric under
  // w -> -w, so -wo serves as well as the mirror image).
  const Vec3 wo_up = wo.z > 0.f ? wo : -wo;
  const float visible = facets_.visible_pdf(wo_up, h.wm);
  if (wo.z * wi.z > 0.f) return visible * h.fresnel / (4.f * std::fabs(h.co));
  // |d wm / d wi| = eta^2 |wi.m| / (eta wi.m + wo.m)^2.
  return visible * (1.f - h.fresnel) * h.eta * h.eta * std::fabs(h.ci) / (h.denom * h.denom);
}

bool RoughDielectricBsdf::sample(const Vec3& wo, float u_lobe, float u1, float u2,
                                 BsdfSample& out) const {
  if (wo.z == 0.f) return false;
  if (facets_.is_smooth()) return smooth_.sample(wo, u_lobe, u1, u2, out);
  if (index_matched_) {
    out.wi = -wo;
    out.weight = tint_;
    out.pdf = 0.f;
    out.specular = true;
    return true;
  }
  const Vec3 wo_up = wo.z > 0.f ? wo : -wo;
  const Vec3 wm = facets_.sample_visible(wo_up, u1, u2);
  const float co = dot(wo, wm);                      // same sign as wo.z
  const float eta = wo.z > 0.f ? ior_ : 1.f / ior_;  // eta_t / eta_i
  float cos_t = 0.f;
  const float f = fresnel_dielectric(std::fabs(co), eta, cos_t);
  Vec3 wi;
  if (u_lobe < f) {
    wi = normalize(reflect_about(wo, wm));
    if (wi.z * wo.z <= 0.f) return false;
  } else {
    // Snell about the micro-normal turned to wo's side.
    const Vec3 n = co > 0.f ? wm : -wm;
    wi = normalize(-wo / eta + n * (std::fabs(co) / eta - cos_t));
    if (wi.z * wo.z >= 0.f) return false;
  }
  out.pdf = pdf(wo, wi);
  if (!(out.pdf > 0.f)) return false;
  out.weight = eval(wo, wi) / out.pdf;
  out.wi = wi;
  out.specular = false;
  out.eta = wi.z * wo.z < 0.f ? eta : 1.f;
  return true;
}

}  // namespace rayfarm
