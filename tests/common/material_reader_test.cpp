// The material kinds of the scene format (common/scene/material_reader.cpp): defaults, synonyms,
// and every out-of-range value rejected with a SceneError naming the file and the JSON pointer.
#include <gtest/gtest.h>

#include <initializer_list>
#include <string>
#include <variant>
#include <vector>

#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

/// A valid scene whose only material is `material` (a JSON object) named "m".
std::string scene_with_material(const std::string& material) {
  return R"({
  "camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
  "film": {"width": 16, "height": 16},
  "materials": {"m": )" +
         material + R"(},
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}]
}
)";
}

/// The scene's warnings but the one every scene without light gets (tested in
/// gltf_conformance_test.cpp): these scenes are unlit on purpose.
std::vector<std::string> warnings(const Scene& scene) {
  std::vector<std::string> out;
  for (const std::string& w : scene.warnings)
    if (w.find(kNoLightWarning) == std::string::npos) out.push_back(w);
  return out;
}

/// The parameters of the one material of a scene built around `material`, which must have no
/// warnings.
template <class K>
K load_params(const std::string& material) {
  TempDir dir;
  const Scene scene = load_scene(dir.write("scene.json", scene_with_material(material)));
  std::string all;
  for (const std::string& w : warnings(scene)) all += w + "\n";
  EXPECT_TRUE(warnings(scene).empty()) << all;
  const K* k = std::get_if<K>(&scene.materials.at(0).kind);
  EXPECT_NE(k, nullptr) << material;
  return k != nullptr ? *k : K{};
}

/// Expects a SceneError naming the file and containing every one of `parts`.
void expect_material_error(const std::string& material, std::initializer_list<std::string> parts) {
  TempDir dir;
  const fs::path file = dir.write("scene.json", scene_with_material(material));
  try {
    (void)load_scene(file);
    ADD_FAILURE() << "expected a SceneError for " << material;
  } catch (const SceneError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(file.string()), std::string::npos) << message;
    for (const std::string& part : parts)
      EXPECT_NE(message.find(part), std::string::npos) << "\"" << part << "\" not in: " << message;
  }
}

TEST(MaterialReader, RoughConductorDefaultsAreRoughGold) {
  const auto c = load_params<RoughConductorMaterial>(R"({"type": "roughconductor"})");
  EXPECT_EQ(c.eta, Vec3(0.143119f, 0.374957f, 1.44248f));
  EXPECT_EQ(c.k, Vec3(3.98316f, 2.38572f, 1.60322f));
  EXPECT_FALSE(c.use_f0);
  EXPECT_EQ(c.alpha_u, 0.1f);
  EXPECT_EQ(c.alpha_v, 0.1f);
  EXPECT_EQ(c.specular_reflectance, Vec3(1.f));
}

TEST(MaterialReader, RoughConductorKeys) {
  auto c = load_params<RoughConductorMaterial>(
      R"({"type": "roughconductor", "eta": [0.2, 0.9, 1.1], "k": [3, 2.5, 2], "alpha": 0.3,
          "specular_reflectance": [0.9, 0.8, 0.7]})");
  EXPECT_EQ(c.eta, Vec3(0.2f, 0.9f, 1.1f));
  EXPECT_EQ(c.k, Vec3(3.f, 2.5f, 2.f));
  EXPECT_EQ(c.alpha_u, 0.3f);
  EXPECT_EQ(c.alpha_v, 0.3f);
  EXPECT_EQ(c.specular_reflectance, Vec3(0.9f, 0.8f, 0.7f));
  c = load_params<RoughConductorMaterial>(
      R"({"type": "roughconductor", "f0": [1, 0.8, 0.3], "alpha_u": 0.5, "alpha_v": 0.05})");
  EXPECT_TRUE(c.use_f0);
  EXPECT_EQ(c.f0, Vec3(1.f, 0.8f, 0.3f));
  EXPECT_EQ(c.alpha_u, 0.5f);
  EXPECT_EQ(c.alpha_v, 0.05f);
}

TEST(MaterialReader, ConductorIsTheSmoothRoughConductor) {
  const auto c = load_params<RoughConductorMaterial>(R"({"type": "conductor", "f0": [1, 1, 1]})");
  EXPECT_EQ(c.alpha_u, 0.f);
  EXPECT_EQ(c.alpha_v, 0.f);
  EXPECT_TRUE(c.use_f0);
}

TEST(MaterialReader, RoughConductorErrors) {
  expect_material_error(R"({"type": "roughconductor", "alpha": 1.5})",
                        {"/materials/m/alpha", "[0, 1]", "1.5"});
  expect_material_error(R"({"type": "roughconductor", "alpha": -0.1})", {"/materials/m/alpha"});
  expect_material_error(
      R"({"type": "roughconductor", "alpha": 0.1, "alpha_u": 0.2, "alpha_v": 0.2})",
      {"/materials/m/alpha_u", "either"});
  expect_material_error(R"({"type": "roughconductor", "alpha_u": 0.2})",
                        {"/materials/m", "\"alpha_u\" needs \"alpha_v\""});
  expect_material_error(R"({"type": "roughconductor", "f0": [1, 1, 1], "eta": [1, 1, 1]})",
                        {"/materials/m/eta", "either"});
  expect_material_error(R"({"type": "roughconductor", "eta": [1, 0, 1]})",
                        {"/materials/m/eta", "> 0"});
  expect_material_error(R"({"type": "roughconductor", "k": [1, -1, 1]})",
                        {"/materials/m/k", ">= 0"});
  expect_material_error(R"({"type": "roughconductor", "f0": [1, 1.2, 1]})",
                        {"/materials/m/f0/1", "[0, 1]"});
  expect_material_error(R"({"type": "roughconductor", "specular_reflectance": [2, 1, 1]})",
                        {"/materials/m/specular_reflectance/0"});
}

TEST(MaterialReader, RoughDielectric) {
  auto d = load_params<RoughDielectricMaterial>(R"({"type": "roughdielectric"})");
  EXPECT_EQ(d.ior, 1.5f);
  EXPECT_EQ(d.alpha_u, 0.1f);
  EXPECT_EQ(d.tint, Vec3(1.f));
  d = load_params<RoughDielectricMaterial>(
      R"({"type": "roughdielectric", "ior": 1.33, "alpha_u": 0.2, "alpha_v": 0.4, "tint": [1, 0.9, 0.8]})");
  EXPECT_EQ(d.ior, 1.33f);
  EXPECT_EQ(d.alpha_u, 0.2f);
  EXPECT_EQ(d.alpha_v, 0.4f);
  EXPECT_EQ(d.tint, Vec3(1.f, 0.9f, 0.8f));
  expect_material_error(R"({"type": "roughdielectric", "ior": -1})",
                        {"/materials/m/ior", "positive"});
  expect_material_error(R"({"type": "roughdielectric", "alpha_v": 2, "alpha_u": 0.1})",
                        {"/materials/m/alpha_v", "[0, 1]"});
  expect_material_error(R"({"type": "roughdielectric", "tint": [0, 0, 1.1]})",
                        {"/materials/m/tint/2"});
}

TEST(MaterialReader, ThinDielectric) {
  auto d = load_params<ThinDielectricMaterial>(R"({"type": "thindielectric"})");
  EXPECT_EQ(d.ior, 1.5f);
  EXPECT_EQ(d.tint, Vec3(1.f));
  d = load_params<ThinDielectricMaterial>(
      R"({"type": "thindielectric", "ior": 1.2, "tint": [0.5, 1, 1]})");
  EXPECT_EQ(d.ior, 1.2f);
  EXPECT_EQ(d.tint, Vec3(0.5f, 1.f, 1.f));
  expect_material_error(R"({"type": "thindielectric", "ior": 0})",
                        {"/materials/m/ior", "positive"});
}

TEST(MaterialReader, PlasticAndRoughPlastic) {
  auto p = load_params<PlasticMaterial>(R"({"type": "plastic"})");
  EXPECT_EQ(p.ior, 1.49f);
  EXPECT_EQ(p.alpha, 0.f);
  EXPECT_FALSE(p.nonlinear);
  EXPECT_EQ(p.diffuse_reflectance, Vec3(0.5f));
  p = load_params<PlasticMaterial>(
      R"({"type": "plastic", "diffuse_reflectance": [0.1, 0.2, 0.3], "ior": 1.6, "alpha": 0.2, "nonlinear": true})");
  EXPECT_EQ(p.diffuse_reflectance, Vec3(0.1f, 0.2f, 0.3f));
  EXPECT_EQ(p.ior, 1.6f);
  EXPECT_EQ(p.alpha, 0.2f);
  EXPECT_TRUE(p.nonlinear);
  p = load_params<PlasticMaterial>(R"({"type": "roughplastic"})");
  EXPECT_EQ(p.alpha, 0.1f);
  p = load_params<PlasticMaterial>(R"({"type": "roughplastic", "alpha": 0.4})");
  EXPECT_EQ(p.alpha, 0.4f);
  expect_material_error(R"({"type": "roughplastic", "alpha": 0})",
                        {"/materials/m/alpha", "alpha > 0"});
  expect_material_error(R"({"type": "plastic", "nonlinear": 1})", {"/materials/m/nonlinear"});
  expect_material_error(R"({"type": "plastic", "alpha": 3})", {"/materials/m/alpha", "[0, 1]"});
}

TEST(MaterialReader, MicrofacetDistribution) {
  // GGX unless "distribution" says otherwise, on each of the three rough kinds.
  EXPECT_EQ(load_params<RoughConductorMaterial>(R"({"type": "roughconductor"})").distribution,
            MicrofacetType::kGgx);
  EXPECT_EQ(load_params<RoughDielectricMaterial>(R"({"type": "roughdielectric"})").distribution,
            MicrofacetType::kGgx);
  EXPECT_EQ(load_params<PlasticMaterial>(R"({"type": "roughplastic"})").distribution,
            MicrofacetType::kGgx);
  const auto c = load_params<RoughConductorMaterial>(
      R"({"type": "roughconductor", "alpha_u": 0.2, "alpha_v": 0.3, "distribution": "beckmann"})");
  EXPECT_EQ(c.distribution, MicrofacetType::kBeckmann);
  EXPECT_EQ(c.alpha_u, 0.2f);
  EXPECT_EQ(c.alpha_v, 0.3f);
  EXPECT_EQ(
      load_params<RoughConductorMaterial>(R"({"type": "roughconductor", "distribution": "ggx"})")
          .distribution,
      MicrofacetType::kGgx);
  EXPECT_EQ(load_params<RoughDielectricMaterial>(
                R"({"type": "roughdielectric", "distribution": "beckmann"})")
                .distribution,
            MicrofacetType::kBeckmann);
  const auto p = load_params<PlasticMaterial>(
      R"({"type": "roughplastic", "alpha": 0.3, "distribution": "beckmann"})");
  EXPECT_EQ(p.distribution, MicrofacetType::kBeckmann);
  EXPECT_EQ(p.alpha, 0.3f);
  EXPECT_EQ(load_params<PlasticMaterial>(R"({"type": "plastic", "distribution": "beckmann"})")
                .distribution,
            MicrofacetType::kBeckmann);

  expect_material_error(R"({"type": "roughconductor", "distribution": "phong"})",
                        {"/materials/m/distribution", "\"phong\"", "ggx or beckmann"});
  expect_material_error(R"({"type": "roughdielectric", "distribution": "Beckmann"})",
                        {"/materials/m/distribution", "\"Beckmann\""});
  expect_material_error(R"({"type": "roughplastic", "distribution": 1})",
                        {"/materials/m/distribution"});
  // Kinds without microfacets do not take the key: a warning names it, as for any unknown key.
  for (const char* material : {R"({"type": "conductor", "distribution": "beckmann"})",
                               R"({"type": "dielectric", "distribution": "ggx"})"}) {
    TempDir dir;
    const Scene scene = load_scene(dir.write("scene.json", scene_with_material(material)));
    ASSERT_EQ(warnings(scene).size(), 1u) << material;
    EXPECT_NE(warnings(scene)[0].find("/materials/m/distribution"), std::string::npos)
        << warnings(scene)[0];
  }
}

TEST(MaterialReader, CoverageIsACutoffOrAProbability) {
  TempDir dir;
  const Scene scene = load_scene(dir.write(
      "scene.json",
      scene_with_material(R"({"type": "diffuse", "opacity": 0.3, "coverage": "blend"})")));
  const Material& m = scene.materials.at(0);
  EXPECT_TRUE(m.alpha_blend);
  EXPECT_TRUE(m.has_alpha());
  EXPECT_EQ(m.alpha.value, 0.3f);
  const Scene cut = load_scene(dir.write(
      "cut.json",
      scene_with_material(R"({"type": "diffuse", "opacity": 0.7, "coverage": "cutoff"})")));
  EXPECT_FALSE(cut.materials.at(0).alpha_blend);
  EXPECT_FALSE(cut.materials.at(0).has_alpha());  // 0.7 is above the cutoff: wholly there
  expect_material_error(R"({"type": "diffuse", "opacity": 0.5, "coverage": "dither"})",
                        {"/materials/m/coverage", "\"dither\"", "cutoff", "blend"});
}

TEST(MaterialReader, MetallicRoughness) {
  auto m = load_params<MetallicRoughnessMaterial>(R"({"type": "metallic_roughness"})");
  EXPECT_EQ(m.base_color, Vec3(1.f));
  EXPECT_EQ(m.metallic, 1.f);
  EXPECT_EQ(m.roughness, 1.f);
  EXPECT_EQ(m.ior, 1.5f);
  EXPECT_EQ(m.transmission, 0.f);
  m = load_params<MetallicRoughnessMaterial>(
      R"({"type": "metallic_roughness", "base_color": [0.5, 0.4, 0.3], "metallic": 0, "roughness": 0.25,
          "ior": 1.33, "transmission": 0.8})");
  EXPECT_EQ(m.base_color, Vec3(0.5f, 0.4f, 0.3f));
  EXPECT_EQ(m.metallic, 0.f);
  EXPECT_EQ(m.roughness, 0.25f);
  EXPECT_EQ(m.ior, 1.33f);
  EXPECT_EQ(m.transmission, 0.8f);
  expect_material_error(R"({"type": "metallic_roughness", "metallic": 1.1})",
                        {"/materials/m/metallic", "[0, 1]"});
  expect_material_error(R"({"type": "metallic_roughness", "roughness": -0.5})",
                        {"/materials/m/roughness"});
  expect_material_error(R"({"type": "metallic_roughness", "transmission": "all"})",
                        {"/materials/m/transmission"});
  expect_material_error(R"({"type": "metallic_roughness", "ior": 0})",
                        {"/materials/m/ior", "positive"});
}

}  // namespace
}  // namespace rayfarm
