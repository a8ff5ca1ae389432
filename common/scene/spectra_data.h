#pragma once
// Published tables behind common/scene/spectra.h: the CIE 1931 observer, the D65 illuminant, and
// the named indices of refraction of Mitsuba 3 scenes.
#include <array>
#include <span>
#include <string_view>

namespace rayfarm::spectra_data {

inline constexpr double kCieMinNm = 360.0;
inline constexpr double kCieMaxNm = 830.0;
inline constexpr int kCieSamples = 95;  ///< every 5 nm from kCieMinNm to kCieMaxNm

extern const std::array<double, kCieSamples> kCie1931X;
extern const std::array<double, kCieSamples> kCie1931Y;
extern const std::array<double, kCieSamples> kCie1931Z;
extern const std::array<double, kCieSamples> kD65;

/// A dielectric's name and index of refraction.
struct NamedIor {
  std::string_view name;
  float ior;
};
std::span<const NamedIor> named_iors();

/// A conductor's name and its eta, k per linear sRGB channel (red, green, blue).
struct NamedConductor {
  std::string_view name;
  float eta[3];
  float k[3];
};
std::span<const NamedConductor> named_conductors();

}  // namespace rayfarm::spectra_data
