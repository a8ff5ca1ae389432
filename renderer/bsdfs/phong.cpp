#include "renderer/bsdfs/phong.h"

#include <algorithm>
#include <cmath>

namespace rayfarm {
namespace {

// Probability of choosing the specular lobe: the ratio of luminances.
inline float specular_probability(const PhongMaterial& m) {
  const float ls = luminance(m.ks), ld = luminance(m.kd);
  return ls + ld > 0.f ? ls / (ls + ld) : 0.f;
}

// Normalised Phong lobe: (n + 2) / (2 pi) cos^n(alpha) for the BRDF, (n + 1) / (2 pi) for the pdf.
inline float cos_alpha_pow(const Vec3& wo, const Vec3& wi, float exponent) {
  // The dot product of unit vectors may round above 1, and (1 + 6e-8)^n overflows for the huge
  // exponents the format allows (n = 1e30 gave infinite weights).
  const float c = std::min(1.f, dot(reflect_z(wo), wi));
  return c > 0.f ? std::pow(c, exponent) : 0.f;
}

// eval and pdf with wo and wi on the upper side.
Vec3 eval_upper(const PhongMaterial& m, const Vec3& wo, const Vec3& wi) {
  const float lobe = cos_alpha_pow(wo, wi, m.exponent) * (m.exponent + 2.f) * (0.5f * kInvPi);
  return (m.kd * kInvPi + m.ks * lobe) * wi.z;
}

float pdf_upper(const PhongMaterial& m, const Vec3& wo, const Vec3& wi) {
  const float ps = specular_probability(m);
  const float spec = cos_alpha_pow(wo, wi, m.exponent) * (m.exponent + 1.f) * (0.5f * kInvPi);
  return (1.f - ps) * wi.z * kInvPi + ps * spec;
}

// Direction around `axis` with density (n + 1) / (2 pi) cos^n.
Vec3 sample_lobe(const Vec3& axis, float exponent, float u1, float u2) {
  const float cos_a = std::pow(u1, 1.f / (exponent + 1.f));
  const float sin_a = std::sqrt(std::max(0.f, 1.f - cos_a * cos_a));
  const float phi = 2.f * kPi * u2;
  return Frame(axis).to_world({std::cos(phi) * sin_a, std::sin(phi) * sin_a, cos_a});
}

}  // namespace

Vec3 PhongBsdf::eval(const Vec3& wo, const Vec3& wi) const {
  if (wo.z * wi.z <= 0.f) return Vec3(0.f);
  const bool flip = wo.z < 0.f;
  return eval_upper(m_, to_upper(wo, flip), to_upper(wi, flip));
}

float PhongBsdf::pdf(const Vec3& wo, const Vec3& wi) const {
  if (wo.z * wi.z <= 0.f) return 0.f;
  const bool flip = wo.z < 0.f;
  return pdf_upper(m_, to_upper(wo, flip), to_upper(wi, flip));
}

bool PhongBsdf::sample(const Vec3& wo_in, float u_lobe, float u1, float u2, BsdfSample& out) const {
  if (wo_in.z == 0.f) return false;
  const bool flip = wo_in.z < 0.f;
  const Vec3 wo = to_upper(wo_in, flip);
  const float ps = specular_probability(m_);
  const Vec3 wi = u_lobe < ps ? sample_lobe(reflect_z(wo), m_.exponent, u1, u2)
                              : sample_cosine_hemisphere(u1, u2);
  if (wi.z <= 0.f) return false;
  out.pdf = pdf_upper(m_, wo, wi);
  if (!(out.pdf > 0.f)) return false;
  out.weight = eval_upper(m_, wo, wi) / out.pdf;
  out.wi = to_upper(wi, flip);
  out.specular = false;
  return true;
}

}  // namespace rayfarm
