#pragma once
// What a rough dielectric coating lets through to the diffuse base beneath it (plastic.h): the
// fraction T(mu) of the light arriving at incidence cosine mu that the micro-facets refract
// inwards (single scattering, the rest being the coat's specular lobe or lost between facets),
// and the fraction Ri of the base's diffuse light that the coating reflects back inside. Both are
// integrals over the visible micro-normals, too costly for a path vertex: they are tabulated once
// per scene (SceneData) over mu and, for a textured roughness, over alpha.
#include <vector>

#include "common/scene/scene.h"

namespace rayfarm {

/// Fraction of the light arriving from outside at incidence cosine mu (in [0, 1]) that a rough
/// interface of relative index eta (inside over outside) transmits in one scattering: the
/// integral over the visible normals wm of (1 - F(wi.wm)) G1(wt), wt the refracted direction.
/// Computed by Gauss-Legendre quadrature over the visible normals' sampling square (32 x 32
/// nodes when eta > 1, else 128 x 128: total internal reflection makes the integrand jump).
float rough_interface_transmittance(MicrofacetType type, float alpha, float eta, float mu);
/// The same for the reflected light: the integral of F(wi.wm) G1(wr), wr the mirrored direction.
float rough_interface_reflectance(MicrofacetType type, float alpha, float eta, float mu);

/// A rough coating's T(mu) and Ri, tabulated for one index and distribution. Ri is 2 x the plain
/// mean over the grid's cosines of R(mu) mu, R the interface's reflectance from inside (index
/// 1 / ior). T and R are tabulated over 64 cosines
/// mu_i = max(1e-6, i / 63), read by linear interpolation, and either for one roughness (the
/// material's constant alpha, exact) or for 64 roughnesses evenly spaced in cbrt(alpha) over
/// [0, 1] (a textured alpha), read by linear interpolation in cbrt(alpha): near alpha 0, T at
/// grazing cosines grows like alpha^0.8, smooth in cbrt(alpha) where sqrt(alpha) left errors of
/// 8e-3.
class RoughCoatTable {
 public:
  static constexpr int kCosines = 64;
  static constexpr int kRoughnesses = 64;

  /// The table for the constant roughness `alpha`, or for all of [0, 1] when `textured`.
  RoughCoatTable(float ior, MicrofacetType type, float alpha, bool textured);

  /// The table's rows interpolated at one roughness: what a BSDF keeps for its vertex.
  struct Coat {
    const float* row0 = nullptr;  ///< T at the roughness node below alpha
    const float* row1 = nullptr;  ///< and above
    float weight = 0.f;           ///< of row1
    float internal = 0.f;         ///< Ri at alpha
    /// T(mu), mu in [0, 1].
    float transmittance(float mu) const {
      const float x = mu * float(kCosines - 1);
      int i = int(x);
      if (i > kCosines - 2) i = kCosines - 2;
      const float t = x - float(i);
      const float a = row0[i] + (row0[i + 1] - row0[i]) * t;
      const float b = row1[i] + (row1[i + 1] - row1[i]) * t;
      return a + (b - a) * weight;
    }
  };
  /// The coat at roughness alpha (the constant one when the table has one roughness).
  Coat at(float alpha) const;

  float ior() const { return ior_; }
  MicrofacetType type() const { return type_; }
  float alpha() const { return alpha_; }
  bool textured() const { return textured_; }
  /// The roughness of a textured table's row.
  static float row_roughness(int row);

 private:
  float ior_;
  MicrofacetType type_;
  float alpha_;
  bool textured_;
  std::vector<float> transmittance_;  // row after row of kCosines
  std::vector<float> internal_;       // one per row
};

/// A table for a plastic built outside a prepared scene (tests, tools): made on first use and
/// kept for the thread's life, one per distinct (ior, distribution, alpha).
const RoughCoatTable& unprepared_rough_coat(float ior, MicrofacetType type, float alpha);

}  // namespace rayfarm
