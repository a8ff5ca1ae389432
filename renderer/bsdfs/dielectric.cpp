#include "renderer/bsdfs/dielectric.h"

#include <cmath>

namespace rayfarm {

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

bool DielectricBsdf::sample(const Vec3& wo, float u_lobe, float /*u1*/, float /*u2*/,
                            BsdfSample& out) const {
  if (wo.z == 0.f) return false;
  const bool entering = wo.z > 0.f;
  const float eta = entering ? ior_ : 1.f / ior_;  // eta_t / eta_i
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
  out.weight = tint_ * static_cast<float>(1.0 / (double(eta) * double(eta)));
  out.eta = eta;
  return true;
}

}  // namespace rayfarm
