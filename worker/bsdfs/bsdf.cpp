#include "worker/bsdfs/bsdf.h"

#include <algorithm>
#include <cmath>

namespace rayfarm {
namespace {

// Two-sided surfaces: mirror both directions to the upper hemisphere of wo.
inline Vec3 to_upper(const Vec3& w, bool flip) { return flip ? Vec3{w.x, w.y, -w.z} : w; }
inline Vec3 reflect_z(const Vec3& w) { return {-w.x, -w.y, w.z}; }

// Probability of choosing the specular lobe of a Phong material: the ratio of luminances.
inline float phong_specular_probability(const Material& m) {
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

Vec3 eval_phong(const Material& m, const Vec3& wo, const Vec3& wi) {
  const float lobe = cos_alpha_pow(wo, wi, m.exponent) * (m.exponent + 2.f) * (0.5f * kInvPi);
  return (m.kd * kInvPi + m.ks * lobe) * wi.z;
}

float pdf_phong(const Material& m, const Vec3& wo, const Vec3& wi) {
  const float ps = phong_specular_probability(m);
  const float spec = cos_alpha_pow(wo, wi, m.exponent) * (m.exponent + 1.f) * (0.5f * kInvPi);
  return (1.f - ps) * wi.z * kInvPi + ps * spec;
}

// Direction around `axis` with density (n + 1) / (2 pi) cos^n.
Vec3 sample_phong_lobe(const Vec3& axis, float exponent, float u1, float u2) {
  const float cos_a = std::pow(u1, 1.f / (exponent + 1.f));
  const float sin_a = std::sqrt(std::max(0.f, 1.f - cos_a * cos_a));
  const float phi = 2.f * kPi * u2;
  return Frame(axis).to_world({std::cos(phi) * sin_a, std::sin(phi) * sin_a, cos_a});
}

bool sample_dielectric(const Material& m, const Vec3& wo, float u_lobe, BsdfSample& out) {
  const bool entering = wo.z > 0.f;
  const float eta = entering ? m.ior : 1.f / m.ior;  // eta_t / eta_i
  const float cos_o = std::fabs(wo.z);
  float cos_t = 0.f;
  const float f = fresnel_dielectric(cos_o, eta, cos_t);
  out.specular = true;
  out.pdf = 0.f;
  if (u_lobe < f) {
    out.wi = reflect_z(wo);
    out.weight = Vec3(1.f);
    return true;
  }
  // Refraction: the tangential part of wi is -wo's divided by eta (Snell), the normal part is
  // cos_t on the far side. Written this way, not as -wo / eta + (cos_o / eta - cos_t) n, so that
  // nothing cancels and a huge 1 / eta cannot overflow.
  const float n_z = entering ? 1.f : -1.f;
  out.wi = normalize(Vec3{-wo.x / eta, -wo.y / eta, -cos_t * n_z});
  // Radiance is compressed by (eta_i / eta_t)^2 crossing the interface; eta^2 in double, so that
  // IORs up to 1e30 neither overflow nor underflow before the division.
  out.weight = m.tint * static_cast<float>(1.0 / (double(eta) * double(eta)));
  return true;
}

}  // namespace

float fresnel_dielectric(float cos_i, float eta, float& cos_t) {
  // In double: the scene format allows IORs from 1e-30 to 1e30, whose squares overflow or
  // underflow a float (eta = 1e20 gave NaN and a black sphere instead of a mirror).
  // cos_t^2 = 1 - sin_i^2 / eta^2, written without the cancellation of 1 - (1 - cos_i^2) that
  // would turn grazing rays at eta = 1 into total internal reflection.
  const double e = eta, ci = cos_i;
  const double cos2_t = (e * e - 1.0 + ci * ci) / (e * e);
  if (!(cos2_t > 0.0)) {
    cos_t = 0.f;
    return 1.f;  // total internal reflection
  }
  const double ct = std::sqrt(cos2_t);
  cos_t = static_cast<float>(ct);
  const double r_parl = (e * ci - ct) / (e * ci + ct);
  const double r_perp = (ci - e * ct) / (ci + e * ct);
  return static_cast<float>(0.5 * (r_parl * r_parl + r_perp * r_perp));
}

Vec3 sample_cosine_hemisphere(float u1, float u2) {
  // Concentric disk mapping (Shirley-Chiu), then lift to the hemisphere.
  const float a = 2.f * u1 - 1.f, b = 2.f * u2 - 1.f;
  float r = 0.f, phi = 0.f;
  if (a == 0.f && b == 0.f) return {0.f, 0.f, 1.f};
  if (std::fabs(a) > std::fabs(b)) {
    r = a;
    phi = (kPi / 4.f) * (b / a);
  } else {
    r = b;
    phi = (kPi / 2.f) - (kPi / 4.f) * (a / b);
  }
  const float x = r * std::cos(phi), y = r * std::sin(phi);
  return {x, y, std::sqrt(std::max(0.f, 1.f - x * x - y * y))};
}

Vec3 Bsdf::eval_other(const Vec3& wo_in, const Vec3& wi_in) const {
  if (is_specular() || wo_in.z * wi_in.z <= 0.f) return Vec3(0.f);
  const bool flip = wo_in.z < 0.f;
  return eval_phong(*m_, to_upper(wo_in, flip), to_upper(wi_in, flip));
}

float Bsdf::pdf_other(const Vec3& wo_in, const Vec3& wi_in) const {
  if (is_specular() || wo_in.z * wi_in.z <= 0.f) return 0.f;
  const bool flip = wo_in.z < 0.f;
  return pdf_phong(*m_, to_upper(wo_in, flip), to_upper(wi_in, flip));
}

bool Bsdf::sample(const Vec3& wo_in, float u_lobe, float u1, float u2, BsdfSample& out) const {
  if (wo_in.z == 0.f) return false;
  switch (kDiffuseOnlyBuild ? MaterialType::kDiffuse : m_->type) {
    case MaterialType::kDielectric:
      return sample_dielectric(*m_, wo_in, u_lobe, out);
    case MaterialType::kMirror:
      out.wi = reflect_z(wo_in);
      out.weight = m_->reflectance;
      out.pdf = 0.f;
      out.specular = true;
      return true;
    case MaterialType::kDiffuse: {
      const bool flip = wo_in.z < 0.f;
      const Vec3 wi = sample_cosine_hemisphere(u1, u2);
      if (wi.z <= 0.f) return false;
      out.wi = to_upper(wi, flip);
      out.weight = m_->albedo;
      out.pdf = wi.z * kInvPi;
      out.specular = false;
      return true;
    }
    case MaterialType::kPhong: {
      const bool flip = wo_in.z < 0.f;
      const Vec3 wo = to_upper(wo_in, flip);
      const float ps = phong_specular_probability(*m_);
      const Vec3 wi = u_lobe < ps ? sample_phong_lobe(reflect_z(wo), m_->exponent, u1, u2)
                                  : sample_cosine_hemisphere(u1, u2);
      if (wi.z <= 0.f) return false;
      out.pdf = pdf_phong(*m_, wo, wi);
      if (!(out.pdf > 0.f)) return false;
      out.weight = eval_phong(*m_, wo, wi) / out.pdf;
      out.wi = to_upper(wi, flip);
      out.specular = false;
      return true;
    }
  }
  return false;
}

}  // namespace rayfarm
