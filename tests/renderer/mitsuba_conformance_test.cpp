// Mitsuba 3's own render tests as rayfarm's conformance suite (docs/conformance.md): each scene
// of tests/data/mitsuba, read by our importer and rendered by our path tracer, against the image
// Mitsuba rendered, with two tests on every scene:
//   - per pixel and channel, z = (ours - reference) / se_ours, where se_ours^2 is the variance of
//     our pixel mean from the film's exact per-pixel sums, floored by Mitsuba's per-sample variance
//     over our sample count (our estimate reads 0 at an edge none of our samples crossed) and by
//     1e-4 / spp as Mitsuba floors its per-sample variance. Two-sided, at a family-wise
//     significance of 0.01 corrected for the number of values (Sidak), as Mitsuba's test_renders.py
//     does. The reference's own noise is left out: its per-sample variance divided by its sample
//     count (thousands) is small beside ours divided by our few hundred samples.
//   - per 8x8 block and channel, and per channel over the blocks (chi-square), the block z test of
//     tests/support/reference_compare.h with the reference's variance taken as zero: a small bias
//     spread over many pixels shows there before any pixel fails.
// Mitsuba's own form, z = |ours - reference| / sqrt(max(var_ref, 1e-4) / spp), assumes our
// per-sample variance is Mitsuba's; it is printed beside ours, not asserted.
// Scenes that use a plugin rayfarm does not support must fail to load, naming it; a scene whose
// difference docs/mitsuba.md lists under a partly supported plugin is run and its figures
// printed, with only its image mean asserted (docs/conformance.md has the table).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>

#include "common/image/exr.h"
#include "common/image/film.h"
#include "common/image/png.h"
#include "common/scene/parser.h"
#include "tests/support/normal_quantile.h"
#include "tests/support/reference_compare.h"
#include "renderer/renderer.h"

namespace rayfarm {
namespace {

const std::string kRoot = std::string(RAYFARM_SOURCE_DIR) + "/tests/data/mitsuba";

struct Case {
  const char* name;    ///< the test's name
  const char* scene;   ///< under kRoot/tests/scenes
  const char* ref;     ///< the reference's prefix, under the scene's refs/
  uint32_t spp;        ///< our sample count: the suite stays within about a minute on 2 cores
  const char* refuse;  ///< non-null: loading must fail naming this (an unsupported plugin)
  /// Non-null: a known difference, a plugin docs/mitsuba.md lists as partly supported. The
  /// statistics are printed; only the image's mean must agree, per channel within 3%.
  const char* known = nullptr;
  /// Non-null: why the per-pixel test is printed, not asserted (the block tests still are).
  const char* pixels_printed = nullptr;
  /// The reference's own relative error, where it is not negligible beside our noise (a scene
  /// whose every sample is the same): added to every pixel's and block's standard error, in
  /// full (an error of the reference is not noise that averages out over a block).
  double ref_precision = 0.0;
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

class MitsubaConformance : public ::testing::TestWithParam<Case> {};

TEST_P(MitsubaConformance, MatchesMitsubasReference) {
  const Case& c = GetParam();
  const std::string xml = kRoot + "/tests/scenes/" + c.scene;
  if (c.refuse != nullptr) {
    try {
      (void)load_scene(xml, {}, SceneImages::kCheckOnly, {}, kRoot);
      ADD_FAILURE() << c.scene << " loaded, but it uses " << c.refuse << ", which is not supported";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(c.refuse), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("not supported"), std::string::npos) << e.what();
    }
    return;
  }
  const Scene scene = load_scene(xml, {}, SceneImages::kKeep, {}, kRoot);
  const std::string dir = xml.substr(0, xml.rfind('/')) + "/refs/";
  const Image ref = read_exr(dir + c.ref + "_ref_rgb.exr");
  const Image ref_var = read_exr(dir + c.ref + "_ref_rgb_var.exr");
  const uint32_t w = scene.film.width, h = scene.film.height;
  ASSERT_EQ(ref.width, w);
  ASSERT_EQ(ref.height, h);
  ASSERT_EQ(ref_var.width, w);

  RenderSettings settings = scene.render;
  settings.spp = c.spp;
  settings.sampler = SamplerType::kIndependent;  // the per-sample variances below need it
  const Renderer renderer(scene, settings);
  Film film(w, h);
  film.add(renderer.render({0, 0, w, h}, {0, settings.spp}));
  ASSERT_EQ(film.nonfinite(), 0u);

  const size_t values = size_t{w} * h * 3;
  const double z_limit = testing::two_sided_z(1.0 - std::pow(1.0 - 0.01, 1.0 / double(values)));
  std::vector<double> mean(values), var(values), zero(values, 0.0), ref_mean(values);
  double max_z = 0.0, max_z_mitsuba = 0.0;
  size_t fails_mitsuba = 0;
  for (size_t p = 0; p < size_t{w} * h; ++p) {
    const double n = film.spp()[p];
    for (int ch = 0; ch < 3; ++ch) {
      const size_t i = p * 3 + ch;
      const double s = from_fixed(film.sum()[i]), s2 = from_fixed(film.sum_sq()[i]);
      mean[i] = s / n;
      var[i] = std::max(0.0, s2 - s * s / n) / (n * (n - 1.0));
      ref_mean[i] = ref.rgb[i];
      // A pixel's sample variance is itself noisy: at a partly covered edge, none of our
      // samples may hit the rare side, and it reads 0. Mitsuba's per-sample variance (over many
      // more samples) divided by our count floors it there.
      var[i] = std::max({var[i], double(ref_var.rgb[i]) / n, 1e-4 / n});
      var[i] += std::pow(c.ref_precision * ref.rgb[i], 2);
      const double se = std::sqrt(var[i]);
      const double z = (mean[i] - ref.rgb[i]) / se;
      max_z = std::max(max_z, std::fabs(z));
      const double z_m =
          std::fabs(mean[i] - ref.rgb[i]) / std::sqrt(std::max(double(ref_var.rgb[i]), 1e-4) / n);
      max_z_mitsuba = std::max(max_z_mitsuba, z_m);
      fails_mitsuba += z_m >= z_limit;
    }
  }
  std::cout << c.name << ": " << c.spp << " spp; per pixel max |z| " << max_z << " (limit "
            << z_limit << "); Mitsuba's form: max |z| " << max_z_mitsuba << ", " << fails_mitsuba
            << " of " << values << " values beyond the limit\n";
  if (const char* dump = std::getenv("RAYFARM_CONFORMANCE_DUMP")) {  // for a look at a failure
    Image ours = ref, diff = ref;  // the reference's size and header
    for (size_t i = 0; i < values; ++i) {
      ours.rgb[i] = static_cast<float>(mean[i]);
      diff.rgb[i] =
          static_cast<float>(std::fabs(mean[i] - ref.rgb[i]) / std::sqrt(var[i]) / z_limit);
    }
    const std::string base = std::string(dump) + "/" + c.name;
    write_exr(base + "-ours.exr", ours);
    write_png_preview(base + "-ours.png", ours);
    write_png_preview(base + "-ref.png", ref);
    write_png_preview(base + "-z.png", diff);
  }
  if (c.known != nullptr) {
    std::cout << c.name << ": a known difference (" << c.known << "); image means:";
    for (int ch = 0; ch < 3; ++ch) {
      double ours = 0.0, theirs = 0.0;
      for (size_t p = 0; p < size_t{w} * h; ++p)
        ours += mean[p * 3 + ch], theirs += ref_mean[p * 3 + ch];
      std::cout << " " << ours / theirs;
      EXPECT_NEAR(ours / theirs, 1.0, 0.03) << c.name << ", channel " << ch;
    }
    std::cout << " of Mitsuba's\n";
    return;
  }
  if (c.pixels_printed != nullptr) {
    std::cout << c.name << ": the per-pixel test is printed, not asserted: " << c.pixels_printed
              << "\n";
  }
  for (size_t i = 0; i < values && c.pixels_printed == nullptr; ++i) {
    const double z = (mean[i] - ref_mean[i]) / std::sqrt(var[i]);
    EXPECT_LT(std::fabs(z), z_limit)
        << c.name << ": pixel (" << i / 3 % w << ", " << i / 3 / w << ") channel " << i % 3
        << ": ours " << mean[i] << " reference " << ref_mean[i] << " se " << std::sqrt(var[i]);
  }
  testing::Blocks ref_blocks = testing::reduce_to_blocks(ref_mean, zero, w, h);
  for (size_t b = 0; b < ref_blocks.mean.size(); ++b)
    ref_blocks.var[b] = std::pow(c.ref_precision * ref_blocks.mean[b], 2);
  for (int ch = 0; ch < 3; ++ch)
    ref_blocks.image_var[ch] = std::pow(c.ref_precision * ref_blocks.image_mean[ch], 2);
  testing::expect_agreement(testing::reduce_to_blocks(mean, var, w, h), ref_blocks, c.name);
}

// clang-format off
const Case kCases[] = {
    {"arealight", "bsdf_spheres/test_arealight_path.xml", "test_arealight", 2048, nullptr},
    {"bumpmap", "bsdf_spheres/test_bumpmap_path.xml", "test_bumpmap", 2048, nullptr,
     "bumpmap: slopes and silhouettes"},
    {"constant", "bsdf_spheres/test_constant_path.xml", "test_constant", 2048, nullptr,
     "diffuse: the rim of the sphere, 2-3% brighter (docs/conformance.md)"},
    {"envmap", "bsdf_spheres/test_envmap_path.xml", "test_envmap", 2048, nullptr},
    {"normalmap_identity_roughconductor", "bsdf_spheres/test_normalmap_identity_roughconductor_path.xml",
     "test_normalmap_identity_roughconductor", 2048, nullptr,
     "roughconductor: height-correlated masking, a few percent brighter at the silhouette"},
    {"normalmap", "bsdf_spheres/test_normalmap_path.xml", "test_normalmap", 2048, nullptr,
     "normalmap: silhouettes"},
    {"normalmap_roughconductor", "bsdf_spheres/test_normalmap_roughconductor_path.xml",
     "test_normalmap_roughconductor", 2048, nullptr, "normalmap: silhouettes"},
    {"pointlight", "bsdf_spheres/test_pointlight_path.xml", "test_pointlight", 2048, nullptr},
    {"roughdielectric", "bsdf_spheres/test_roughdielectric_path.xml", "test_roughdielectric", 2048, nullptr,
     nullptr, "near-specular highlights of small lights: heavy-tailed pixels"},
    {"roughplastic_linear", "bsdf_spheres/test_roughplastic_linear_path.xml", "test_roughplastic_linear", 4096, nullptr},
    {"roughplastic_nonlinear", "bsdf_spheres/test_roughplastic_nonlinear_path.xml", "test_roughplastic_nonlinear", 2048, nullptr},
    {"textured_diffuse", "bsdf_spheres/test_textured_diffuse_path.xml", "test_textured_diffuse", 2048, nullptr},
    {"textured_roughconductor", "bsdf_spheres/test_textured_roughconductor_path.xml", "test_textured_roughconductor", 2048, nullptr},
    {"texturedprincipled1", "bsdf_spheres/test_texturedprincipled1_path.xml", nullptr, 0, "principled"},
    {"texturedprincipled2", "bsdf_spheres/test_texturedprincipled2_path.xml", nullptr, 0, "principled"},
    {"texturedprincipledthin", "bsdf_spheres/test_texturedprincipledthin_path.xml", nullptr, 0, "principledthin"},
    {"directional", "floating_sphere/test_directional_direct.xml", "test_directional", 2048, nullptr},
    {"infinite_mirrors", "infinite_mirrors/scene_path.xml", "scene", 2048, nullptr},
    // A projector's image is the same at every sample away from its edges: there the reference's
    // own error shows (docs/conformance.md, "The projector").
    {"projector_constant", "projector/test_projector_constant_direct.xml", "test_projector_constant", 2048, nullptr,
     nullptr, nullptr, 1e-3},
    {"projector_textured", "projector/test_projector_textured_direct.xml", "test_projector_textured", 2048, nullptr,
     nullptr, nullptr, 1e-3},
};
// clang-format on

INSTANTIATE_TEST_SUITE_P(Suite, MitsubaConformance, ::testing::ValuesIn(kCases),
                         [](const auto& test) { return std::string(test.param.name); });

}  // namespace
}  // namespace rayfarm
