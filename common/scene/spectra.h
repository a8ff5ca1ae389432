#pragma once
// Spectra as Mitsuba 3 scenes write them, reduced to linear sRGB the way Mitsuba 3's RGB variants
// (scalar_rgb, llvm_rgb, cuda_rgb) reduce them when they load a scene, and the named indices of
// refraction that its dielectrics and conductors accept. rayfarm renders in RGB, so a Mitsuba
// scene rendered here matches the same scene rendered by Mitsuba in an RGB variant.
//
// The rule (Mitsuba 3: `spectrum_list_to_srgb` in src/core/spectrum.cpp, called from
// `create_texture_from_spectrum` in src/core/xml.cpp, `Properties::get_texture_impl` in newer
// releases, and `ior_from_file` in include/mitsuba/render/ior.h):
//   1. the spectrum is the piecewise-linear curve through the (wavelength nm, value) pairs; it is
//      zero outside [first, last] wavelength (nothing is extrapolated);
//   2. every value is multiplied by 1 / 106.7502593994140625 (MI_CIE_Y_NORMALIZATION: the sum
//      below of the CIE y curve alone, so that a constant 1 has luminance 1);
//   3. it is sampled at the 1000 wavelengths w_i = 360 + 470 i / 999 nm, i = 0..999 (both ends
//      included), skipping those outside [first, last];
//   4. XYZ = 470 / 1000 * sum_i value(w_i) * cmf(w_i) [* D65(w_i)], where cmf is the CIE 1931
//      2-degree observer tabulated every 5 nm from 360 to 830 nm and interpolated linearly, and
//      D65 the CIE illuminant on the same grid times 1 / 98.99741751876255;
//   5. linear sRGB = the XYZ-to-Rec.709 matrix (D65 white) times XYZ;
//   6. bounded spectra are clamped to [0, 1], unbounded ones only to >= 0.
// Which spectra are bounded, and which are weighted by D65, depends on where they appear
// (`SpectrumRole`). A single value (`value="0.5"`) is a constant: grey, except directly inside an
// emitter, where a constant spectrum is Mitsuba's equal-energy white, value * M * (1, 1, 1).
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/math/vec3.h"

namespace rayfarm {

/// Where a spectrum appears in a Mitsuba scene, which decides how it becomes RGB.
enum class SpectrumRole {
  /// The default (a BSDF's reflectance, a texture's colour): weighted by D65, clamped to [0, 1].
  reflectance,
  /// A spectrum directly inside an emitter (radiance, irradiance, intensity): not weighted by
  /// D65, only negatives clamped.
  emission,
  /// A parameter named eta, k, int_ior, ext_ior or sigma_t outside an emitter: weighted by D65,
  /// only negatives clamped.
  unbounded,
  /// A named conductor's tabulated eta or k (`material="Au"`): not weighted by D65, only negatives
  /// clamped (`ior_from_file` passes bounded = false, d65 = false).
  tabulated_ior,
};

/// The two switches of the conversion for a role.
struct SpectrumConversion {
  bool bounded;  ///< clamp to [0, 1] rather than only to >= 0
  bool d65;      ///< weight by the D65 illuminant
};
SpectrumConversion spectrum_conversion(SpectrumRole role);

/// True for the parameter names that Mitsuba 3 reads as unbounded spectra outside an emitter.
bool is_unbounded_spectrum_parameter(std::string_view name);

/// Linear sRGB of the piecewise-linear spectrum through (wavelengths_nm[i], values[i]), converted
/// by the rule above. Throws std::invalid_argument (a message without a place, for the reader to
/// prefix) when the sizes differ, fewer than two pairs are given, a number is not finite, or the
/// wavelengths do not strictly increase.
Vec3 spectrum_to_rgb(const std::vector<double>& wavelengths_nm, const std::vector<double>& values,
                     SpectrumRole role);
Vec3 spectrum_to_rgb(const std::vector<double>& wavelengths_nm, const std::vector<double>& values,
                     SpectrumConversion conversion);

/// Linear sRGB of the constant spectrum `value` (`<spectrum value="0.5"/>`). Throws
/// std::invalid_argument when `value` is not finite.
Vec3 uniform_spectrum_to_rgb(double value, SpectrumRole role);

/// The CIE 1931 2-degree colour matching functions (x, y, z) at `nm`, interpolated linearly in the
/// 5 nm table; zero outside [360, 830] nm.
Vec3 cie1931_xyz(double nm);
/// The CIE D65 illuminant at `nm` scaled as Mitsuba scales it (100 at 560 nm / 98.9974...); zero
/// outside [360, 830] nm.
double cie_d65(double nm);
/// XYZ to linear sRGB (Rec. 709 primaries, D65 white), with Mitsuba's matrix.
Vec3 xyz_to_linear_srgb(const Vec3& xyz);

/// The dielectric index of refraction Mitsuba 3 gives a name in `int_ior` / `ext_ior` (vacuum, air,
/// water, bk7, diamond, ...: include/mitsuba/render/ior.h, values at about 589 nm from Hecht's
/// Optics), compared without regard to case; nullopt for an unknown name.
std::optional<float> named_ior(std::string_view name);
/// Every name `named_ior` knows, comma-separated, for error messages.
std::string named_ior_choices();

/// A conductor's complex index of refraction eta + i k per RGB channel.
struct ComplexIor {
  Vec3 eta;
  Vec3 k;
};
/// The complex index of refraction that Mitsuba 3's conductor and roughconductor take for
/// `material` in an RGB variant: its tabulated eta and k spectra converted with
/// SpectrumRole::tabulated_ior. "none" is a perfect mirror (eta 0, k 1). Names are compared as
/// Mitsuba compares file names: case matters. nullopt for an unknown name.
std::optional<ComplexIor> named_conductor(std::string_view material);
/// Every name `named_conductor` knows, comma-separated, for error messages.
std::string named_conductor_choices();

}  // namespace rayfarm
