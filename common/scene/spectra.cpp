// Spectra to linear sRGB as Mitsuba 3's RGB variants convert them (the rule is in spectra.h), and
// the named indices of refraction.
#include "common/scene/spectra.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>

#include "common/scene/spectra_data.h"

namespace rayfarm {
namespace {

using spectra_data::kCieMaxNm;
using spectra_data::kCieMinNm;
using spectra_data::kCieSamples;

// Mitsuba's own constants: the y curve's sum over the 1000 samples (so a constant 1 has luminance
// 1), and D65's scale. They are kept as Mitsuba has them, not recomputed, so that results agree
// with Mitsuba's to the last digits.
constexpr double kCieYNormalization = 1.0 / 106.7502593994140625;
constexpr double kD65Normalization = 1.0 / 98.99741751876255;
constexpr int kSteps = 1000;

/// Index and weight of `nm` in the 5 nm tables; nullopt outside them.
struct TablePlace {
  int i0;
  double w1;
};
std::optional<TablePlace> table_place(double nm) {
  if (!(nm >= kCieMinNm && nm <= kCieMaxNm)) return std::nullopt;
  const double t = (nm - kCieMinNm) * ((kCieSamples - 1) / (kCieMaxNm - kCieMinNm));
  const int i0 = std::clamp(static_cast<int>(t), 0, kCieSamples - 2);
  return TablePlace{i0, t - i0};
}

double lerp_table(const std::array<double, kCieSamples>& table, const TablePlace& p) {
  return (1.0 - p.w1) * table[p.i0] + p.w1 * table[p.i0 + 1];
}

void check_spectrum(const std::vector<double>& wavelengths, const std::vector<double>& values) {
  if (wavelengths.size() != values.size())
    throw std::invalid_argument("spectrum has " + std::to_string(wavelengths.size()) +
                                " wavelengths but " + std::to_string(values.size()) + " values");
  if (wavelengths.size() < 2)
    throw std::invalid_argument(
        "a spectrum needs at least two wavelength:value pairs (or one plain value)");
  for (std::size_t i = 0; i < wavelengths.size(); ++i) {
    if (!std::isfinite(wavelengths[i]) || !std::isfinite(values[i]))
      throw std::invalid_argument("spectrum pair " + std::to_string(i + 1) +
                                  " is not a finite number");
    if (i > 0 && !(wavelengths[i] > wavelengths[i - 1]))
      throw std::invalid_argument("spectrum wavelengths must increase strictly (pair " +
                                  std::to_string(i + 1) + " does not)");
  }
}

}  // namespace

SpectrumConversion spectrum_conversion(SpectrumRole role) {
  switch (role) {
    case SpectrumRole::reflectance:
      return {true, true};
    case SpectrumRole::emission:
      return {false, false};
    case SpectrumRole::unbounded:
      return {false, true};
    case SpectrumRole::tabulated_ior:
      return {false, false};
  }
  return {true, true};
}

bool is_unbounded_spectrum_parameter(std::string_view name) {
  return name == "eta" || name == "k" || name == "int_ior" || name == "ext_ior" ||
         name == "sigma_t";
}

Vec3 cie1931_xyz(double nm) {
  const auto p = table_place(nm);
  if (!p) return Vec3(0.f);
  return {static_cast<float>(lerp_table(spectra_data::kCie1931X, *p)),
          static_cast<float>(lerp_table(spectra_data::kCie1931Y, *p)),
          static_cast<float>(lerp_table(spectra_data::kCie1931Z, *p))};
}

double cie_d65(double nm) {
  const auto p = table_place(nm);
  return p ? lerp_table(spectra_data::kD65, *p) * kD65Normalization : 0.0;
}

namespace {
// Mitsuba's XYZ-to-sRGB matrix (rounded as Mitsuba rounds it), in double for the sums.
void xyz_to_srgb(const double xyz[3], double rgb[3]) {
  rgb[0] = 3.240479 * xyz[0] - 1.537150 * xyz[1] - 0.498535 * xyz[2];
  rgb[1] = -0.969256 * xyz[0] + 1.875991 * xyz[1] + 0.041556 * xyz[2];
  rgb[2] = 0.055648 * xyz[0] - 0.204043 * xyz[1] + 1.057311 * xyz[2];
}
}  // namespace

Vec3 xyz_to_linear_srgb(const Vec3& xyz) {
  const double in[3] = {xyz.x, xyz.y, xyz.z};
  double out[3];
  xyz_to_srgb(in, out);
  return {static_cast<float>(out[0]), static_cast<float>(out[1]), static_cast<float>(out[2])};
}

Vec3 spectrum_to_rgb(const std::vector<double>& wavelengths_nm, const std::vector<double>& values,
                     SpectrumRole role) {
  return spectrum_to_rgb(wavelengths_nm, values, spectrum_conversion(role));
}

Vec3 spectrum_to_rgb(const std::vector<double>& wavelengths_nm, const std::vector<double>& values,
                     SpectrumConversion conversion) {
  check_spectrum(wavelengths_nm, values);
  const double front = wavelengths_nm.front(), back = wavelengths_nm.back();
  double xyz[3] = {0.0, 0.0, 0.0};
  std::size_t segment = 0;  // the samples increase, so the segment only moves forward
  for (int i = 0; i < kSteps; ++i) {
    const double w = kCieMinNm + (i / double(kSteps - 1)) * (kCieMaxNm - kCieMinNm);
    if (w < front || w > back) continue;
    while (segment + 2 < wavelengths_nm.size() && wavelengths_nm[segment + 1] <= w) ++segment;
    const double w0 = wavelengths_nm[segment], w1 = wavelengths_nm[segment + 1];
    const double v = ((w - w1) * values[segment] + (w0 - w) * values[segment + 1]) / (w0 - w1);
    const auto p = table_place(w);
    if (!p) continue;
    double weight = v * kCieYNormalization;
    if (conversion.d65) weight *= lerp_table(spectra_data::kD65, *p) * kD65Normalization;
    xyz[0] += lerp_table(spectra_data::kCie1931X, *p) * weight;
    xyz[1] += lerp_table(spectra_data::kCie1931Y, *p) * weight;
    xyz[2] += lerp_table(spectra_data::kCie1931Z, *p) * weight;
  }
  // The sum covers 470 nm with 1000 samples; Mitsuba divides by the sample count, not by the 999
  // gaps between samples, and that factor is part of what its scenes look like.
  for (double& c : xyz) c *= (kCieMaxNm - kCieMinNm) / kSteps;
  double rgb[3];
  xyz_to_srgb(xyz, rgb);
  for (double& c : rgb) c = conversion.bounded ? std::clamp(c, 0.0, 1.0) : std::max(c, 0.0);
  return {static_cast<float>(rgb[0]), static_cast<float>(rgb[1]), static_cast<float>(rgb[2])};
}

Vec3 uniform_spectrum_to_rgb(double value, SpectrumRole role) {
  if (!std::isfinite(value)) throw std::invalid_argument("spectrum value is not a finite number");
  // Inside an emitter a constant spectrum is equal-energy white, which sRGB (white point D65)
  // sees as slightly purple; Mitsuba's RGB variants keep that colour to match its spectral ones.
  if (role == SpectrumRole::emission) {
    const double ones[3] = {1.0, 1.0, 1.0};
    double rgb[3];
    xyz_to_srgb(ones, rgb);
    return {static_cast<float>(value * rgb[0]), static_cast<float>(value * rgb[1]),
            static_cast<float>(value * rgb[2])};
  }
  return Vec3(static_cast<float>(value));
}

std::optional<float> named_ior(std::string_view name) {
  std::string lower(name);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const auto& entry : spectra_data::named_iors())
    if (entry.name == lower) return entry.ior;
  return std::nullopt;
}

std::string named_ior_choices() {
  std::string out;
  for (const auto& entry : spectra_data::named_iors()) {
    if (!out.empty()) out += ", ";
    out += entry.name;
  }
  return out;
}

std::optional<ComplexIor> named_conductor(std::string_view material) {
  if (material == "none") return ComplexIor{Vec3(0.f), Vec3(1.f)};
  for (const auto& entry : spectra_data::named_conductors())
    if (entry.name == material)
      return ComplexIor{{entry.eta[0], entry.eta[1], entry.eta[2]},
                        {entry.k[0], entry.k[1], entry.k[2]}};
  return std::nullopt;
}

std::string named_conductor_choices() {
  std::string out = "none";
  for (const auto& entry : spectra_data::named_conductors()) out += ", " + std::string(entry.name);
  return out;
}

}  // namespace rayfarm
