// Spectra to linear sRGB by Mitsuba 3's RGB-variant rule (common/scene/spectra.h), and the named
// indices of refraction. Expected numbers were worked out by hand where the text says so, and
// otherwise by scripts/mitsuba-conductors.py, which implements the same rule separately in Python.
#include "common/scene/spectra.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

constexpr double kYNorm = 1.0 / 106.7502593994140625;

void expect_rgb_near(const Vec3& got, const Vec3& want, float tolerance) {
  EXPECT_NEAR(got.x, want.x, tolerance) << "red";
  EXPECT_NEAR(got.y, want.y, tolerance) << "green";
  EXPECT_NEAR(got.z, want.z, tolerance) << "blue";
}

/// The message of the std::invalid_argument that `convert` throws, or "" when none is thrown.
template <class F>
std::string invalid_argument_message(F convert) {
  try {
    convert();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Spectra, ColourMatchingTableIsTheCie1931ObserverEvery5nm) {
  // CIE 1931 at 600 nm: x 1.0622, y 0.631, z 0.0008 (published table).
  expect_rgb_near(cie1931_xyz(600.0), {1.0622f, 0.631f, 0.0008f}, 1e-6f);
  // Halfway between 555 nm (y 1.0) and 560 nm (y 0.995): linear interpolation.
  EXPECT_NEAR(cie1931_xyz(557.5).y, 0.9975f, 1e-6f);
  EXPECT_NEAR(cie1931_xyz(360.0).x, 0.0001299f, 1e-9f);
  EXPECT_NEAR(cie1931_xyz(830.0).x, 0.000001251141f, 1e-12f);
  EXPECT_TRUE(is_black(cie1931_xyz(359.9)));
  EXPECT_TRUE(is_black(cie1931_xyz(830.1)));
  // D65 is 100 at 560 nm before Mitsuba's scale of 1 / 98.99741751876255.
  EXPECT_NEAR(cie_d65(560.0), 100.0 / 98.99741751876255, 1e-9);
  EXPECT_EQ(cie_d65(300.0), 0.0);
}

TEST(Spectra, SamplesAt360Plus470iOver999AndWeighsEachBy047) {
  // A spectrum on [360, 360.4] nm holds only the first sample (the next is at 360.47 nm), so by
  // hand: XYZ = 0.47 * cmf(360) * value / 106.75..., then the matrix, then negatives clamped.
  const double value = 1e6;
  const Vec3 xyz = cie1931_xyz(360.0) * static_cast<float>(0.47 * value * kYNorm);
  const Vec3 want = max(xyz_to_linear_srgb(xyz), Vec3(0.f));
  const Vec3 got = spectrum_to_rgb({360.0, 360.4}, {value, value}, SpectrumRole::emission);
  expect_rgb_near(got, want, 1e-5f);
  EXPECT_GT(got.x, 0.1f);
  // The last sample is exactly 830 nm.
  const Vec3 xyz_last = cie1931_xyz(830.0) * static_cast<float>(0.47 * 1e9 * kYNorm);
  expect_rgb_near(spectrum_to_rgb({829.9, 830.0}, {1e9, 1e9}, SpectrumRole::emission),
                  max(xyz_to_linear_srgb(xyz_last), Vec3(0.f)), 1e-4f);
  // Between two samples (360.5 to 360.9 nm) there is nothing: black, not an interpolation.
  EXPECT_TRUE(is_black(spectrum_to_rgb({360.5, 360.9}, {1e9, 1e9}, SpectrumRole::emission)));
  // Nothing is extrapolated beyond the given wavelengths, and the table ends at 830 nm.
  EXPECT_TRUE(is_black(spectrum_to_rgb({900.0, 1000.0}, {5.0, 5.0}, SpectrumRole::emission)));
}

TEST(Spectra, ConstantOneReflectanceIsWhite) {
  // D65 is sRGB's white, so a D65-weighted constant comes out grey; its level is the sum of
  // D65 * y over the samples (98.888) over Mitsuba's D65 scale (98.997): 0.9989.
  const Vec3 white = spectrum_to_rgb({360.0, 830.0}, {1.0, 1.0}, SpectrumRole::reflectance);
  expect_rgb_near(white, Vec3(0.99889f), 2e-4f);
  EXPECT_NEAR(white.x, white.z, 3e-4f);
}

TEST(Spectra, ConstantOneEmissionIsEqualEnergyWhite) {
  // Not weighted by D65: XYZ ~ (1, 1, 1) (the sums of x, y and z differ by < 0.04%), so RGB is
  // the matrix's row sums (1.2048, 0.9483, 0.9089): the purple-ish equal-energy white.
  const Vec3 rgb = spectrum_to_rgb({360.0, 830.0}, {1.0, 1.0}, SpectrumRole::emission);
  expect_rgb_near(rgb, {1.204794f, 0.948291f, 0.908916f}, 5e-4f);
  expect_rgb_near(uniform_spectrum_to_rgb(1.0, SpectrumRole::emission),
                  {1.204794f, 0.948291f, 0.908916f}, 1e-6f);
  expect_rgb_near(uniform_spectrum_to_rgb(0.5, SpectrumRole::reflectance), Vec3(0.5f), 0.f);
  expect_rgb_near(uniform_spectrum_to_rgb(1.5, SpectrumRole::unbounded), Vec3(1.5f), 0.f);
}

TEST(Spectra, ConstantOver400To700OnlyIsNearlyTheConstant) {
  // Almost all of the D65-weighted matching functions lie within 400-700 nm, so a reflectance of
  // 0.78 there (and 0 elsewhere) is nearly grey 0.78.
  const std::vector<double> wl = {400, 500, 600, 700};
  const Vec3 rgb = spectrum_to_rgb(wl, {0.78, 0.78, 0.78, 0.78}, SpectrumRole::reflectance);
  expect_rgb_near(rgb, {0.776367f, 0.779810f, 0.776029f}, 2e-5f);
  // As emission it takes the equal-energy tint: 0.78 * (1.2048, 0.9483, 0.9089), a little less.
  expect_rgb_near(spectrum_to_rgb(wl, {0.78, 0.78, 0.78, 0.78}, SpectrumRole::emission),
                  {0.935761f, 0.740626f, 0.704686f}, 2e-5f);
}

TEST(Spectra, RisingEmitterIsOrangeAndUnclamped) {
  const std::vector<double> wl = {400, 500, 600, 700};
  const std::vector<double> v = {0, 8, 15.6, 18.4};
  const Vec3 rgb = spectrum_to_rgb(wl, v, SpectrumRole::emission);
  expect_rgb_near(rgb, {20.710837f, 10.854634f, 2.771152f}, 2e-4f);
  EXPECT_GT(rgb.x, rgb.y);
  EXPECT_GT(rgb.y, rgb.z);
  // The same numbers as a reflectance are clamped to 1.
  expect_rgb_near(spectrum_to_rgb(wl, v, SpectrumRole::reflectance), Vec3(1.f), 0.f);
}

TEST(Spectra, ScalingAndAddingSpectraScalesAndAddsRgb) {
  const std::vector<double> wl = {380, 450, 520, 610, 700, 780};
  const std::vector<double> a = {0.1, 0.4, 0.2, 0.9, 0.3, 0.05};
  const std::vector<double> b = {0.5, 0.1, 0.7, 0.2, 0.6, 0.4};
  std::vector<double> sum(wl.size()), scaled(wl.size());
  for (std::size_t i = 0; i < wl.size(); ++i) {
    sum[i] = a[i] + b[i];
    scaled[i] = 3.0 * a[i];
  }
  const Vec3 ra = spectrum_to_rgb(wl, a, SpectrumRole::emission);
  const Vec3 rb = spectrum_to_rgb(wl, b, SpectrumRole::emission);
  ASSERT_GT(min_component(ra), 0.f);  // no clamping, so the map is linear
  ASSERT_GT(min_component(rb), 0.f);
  expect_rgb_near(spectrum_to_rgb(wl, scaled, SpectrumRole::emission), 3.f * ra, 1e-5f);
  expect_rgb_near(spectrum_to_rgb(wl, sum, SpectrumRole::emission), ra + rb, 1e-5f);
  // More reflectance somewhere never means less luminance.
  std::vector<double> more = a;
  more[3] += 0.05;
  EXPECT_GT(luminance(spectrum_to_rgb(wl, more, SpectrumRole::reflectance)),
            luminance(spectrum_to_rgb(wl, a, SpectrumRole::reflectance)));
}

TEST(Spectra, OnlyNegativesAreClampedForUnboundedRoles) {
  // A narrow cyan line at 490 nm lies outside the sRGB gamut: its red is negative (by hand,
  // 3.240 x - 1.537 y - 0.499 z with x, y, z = 0.032, 0.208, 0.465 is -0.45), clamped to 0.
  const std::vector<double> wl = {480, 490, 500};
  const std::vector<double> line = {0, 400, 0};
  for (SpectrumRole role : {SpectrumRole::reflectance, SpectrumRole::emission,
                            SpectrumRole::unbounded, SpectrumRole::tabulated_ior})
    EXPECT_EQ(spectrum_to_rgb(wl, line, role).x, 0.f) << static_cast<int>(role);
  EXPECT_GT(spectrum_to_rgb(wl, line, SpectrumRole::emission).y, 1.f);
  // An index of refraction of 2.5 everywhere stays 2.5 (D65-weighted, so grey).
  const Vec3 eta = spectrum_to_rgb({300, 900}, {2.5, 2.5}, SpectrumRole::unbounded);
  expect_rgb_near(eta, Vec3(2.5f * 0.99889f), 1e-3f);
  EXPECT_EQ(spectrum_to_rgb({300, 900}, {2.5, 2.5}, SpectrumRole::reflectance), Vec3(1.f));
  EXPECT_TRUE(is_unbounded_spectrum_parameter("eta"));
  EXPECT_TRUE(is_unbounded_spectrum_parameter("int_ior"));
  EXPECT_FALSE(is_unbounded_spectrum_parameter("reflectance"));
}

TEST(Spectra, BadSpectraAreRejectedWithAClearMessage) {
  const auto nan = std::numeric_limits<double>::quiet_NaN();
  const auto convert = [](std::vector<double> wl, std::vector<double> v) {
    return [wl, v] { (void)spectrum_to_rgb(wl, v, SpectrumRole::reflectance); };
  };
  EXPECT_NE(invalid_argument_message(convert({500, 400}, {0.1, 0.2})).find("increase"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message(convert({400, 400}, {0.1, 0.2})).find("pair 2"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message(convert({400}, {0.1})).find("at least two"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message(convert({}, {})).find("at least two"), std::string::npos);
  EXPECT_NE(invalid_argument_message(convert({400, 500}, {0.1, nan})).find("pair 2"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message(convert({nan, 500}, {0.1, 0.2})).find("finite"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message(convert({400, 500, 600}, {0.1, 0.2})).find("3 wavelengths"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message([] {
              (void)uniform_spectrum_to_rgb(std::numeric_limits<double>::infinity(),
                                            SpectrumRole::emission);
            }).find("finite"),
            std::string::npos);
}

TEST(Spectra, NamedDielectricsAreMitsubas) {
  EXPECT_EQ(named_ior("bk7"), 1.5046f);
  EXPECT_EQ(named_ior("BK7"), 1.5046f);  // Mitsuba lowers the case first
  EXPECT_EQ(named_ior("vacuum"), 1.0f);
  EXPECT_EQ(named_ior("air"), 1.000277f);
  EXPECT_EQ(named_ior("water"), 1.333f);
  EXPECT_EQ(named_ior("water ice"), 1.31f);
  EXPECT_EQ(named_ior("diamond"), 2.419f);
  EXPECT_FALSE(named_ior("glass").has_value());
  EXPECT_FALSE(named_ior("").has_value());
  const std::string choices = named_ior_choices();
  EXPECT_EQ(choices.rfind("vacuum, helium", 0), 0u) << choices;
  EXPECT_NE(choices.find("pet, diamond"), std::string::npos) << choices;
  EXPECT_EQ(std::count(choices.begin(), choices.end(), ','), 22) << choices;  // 23 names
}

float normal_reflectance(float eta, float k) {
  return ((eta - 1) * (eta - 1) + k * k) / ((eta + 1) * (eta + 1) + k * k);
}
Vec3 normal_reflectance(const ComplexIor& ior) {
  return {normal_reflectance(ior.eta.x, ior.k.x), normal_reflectance(ior.eta.y, ior.k.y),
          normal_reflectance(ior.eta.z, ior.k.z)};
}

TEST(Spectra, NamedConductorsLookLikeTheirMetals) {
  const auto au = named_conductor("Au");
  ASSERT_TRUE(au.has_value());
  EXPECT_GT(au->k.x, au->k.z);
  const Vec3 r_au = normal_reflectance(*au);
  EXPECT_GT(r_au.x, r_au.y);  // yellow: red and green well above blue
  EXPECT_GT(r_au.y, 1.5f * r_au.z);
  const Vec3 r_al = normal_reflectance(*named_conductor("Al"));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(r_al[c], 0.92f, 0.02f) << c;  // bright and grey
  const Vec3 r_cu = normal_reflectance(*named_conductor("Cu"));
  EXPECT_GT(r_cu.x, r_cu.y + 0.2f);  // reddish
  EXPECT_GT(r_cu.y, r_cu.z);
  // Silver as Mitsuba 3 gives it in RGB mode (eta 0.1553 0.1167 0.1384, k 4.8284 3.1222 2.1469).
  const auto ag = named_conductor("Ag");
  ASSERT_TRUE(ag.has_value());
  expect_rgb_near(ag->eta, {0.155276f, 0.116728f, 0.138388f}, 1e-6f);
  expect_rgb_near(ag->k, {4.82835f, 3.12222f, 2.1469f}, 1e-5f);
  const auto none = named_conductor("none");
  ASSERT_TRUE(none.has_value());
  expect_rgb_near(normal_reflectance(*none), Vec3(1.f), 0.f);  // a perfect mirror
  EXPECT_FALSE(named_conductor("au").has_value());             // file names: case matters
  EXPECT_FALSE(named_conductor("gold").has_value());
  const std::string choices = named_conductor_choices();
  EXPECT_EQ(std::count(choices.begin(), choices.end(), ','), 37) << choices;  // none + 37
  EXPECT_NE(choices.find("Na_palik"), std::string::npos);
  EXPECT_NE(choices.find("V_palik, VN, W"), std::string::npos) << choices;
}

/// Reads a Mitsuba .spd file: "wavelength value" lines and '#' comments.
void read_spd(const fs::path& file, std::vector<double>& wl, std::vector<double>& v) {
  std::ifstream in(file);
  ASSERT_TRUE(in) << file;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double w = 0, x = 0;
    ASSERT_TRUE(fields >> w >> x) << file << ": " << line;
    wl.push_back(w);
    v.push_back(x);
  }
}

TEST(Spectra, ConductorTableIsTheSpectraConvertedAndKeepsTheirReflectance) {
  const fs::path dir = fs::path(RAYFARM_SOURCE_DIR) / "tests" / "data" / "ior";
  for (const char* name : {"Au", "Al", "Cu"}) {
    SCOPED_TRACE(name);
    std::vector<double> eta_wl, eta_v, k_wl, k_v;
    read_spd(dir / (std::string(name) + ".eta.spd"), eta_wl, eta_v);
    read_spd(dir / (std::string(name) + ".k.spd"), k_wl, k_v);
    const auto table = named_conductor(name);
    ASSERT_TRUE(table.has_value());
    // The committed table is what this code computes from the measured spectra.
    const Vec3 eta = spectrum_to_rgb(eta_wl, eta_v, SpectrumRole::tabulated_ior);
    const Vec3 k = spectrum_to_rgb(k_wl, k_v, SpectrumRole::tabulated_ior);
    expect_rgb_near(table->eta, eta, 1e-5f * max_component(eta));
    expect_rgb_near(table->k, k, 1e-5f * max_component(k));
    // The normal-incidence reflectance from the RGB eta, k is within 0.035 of the measured
    // spectral reflectance seen as a colour (the table loses the spectral detail of R).
    ASSERT_EQ(eta_wl, k_wl);
    std::vector<double> r(eta_wl.size());
    for (std::size_t i = 0; i < r.size(); ++i)
      r[i] = normal_reflectance(static_cast<float>(eta_v[i]), static_cast<float>(k_v[i]));
    expect_rgb_near(normal_reflectance(*table),
                    spectrum_to_rgb(eta_wl, r, SpectrumRole::reflectance), 0.035f);
  }
}

}  // namespace
}  // namespace rayfarm
