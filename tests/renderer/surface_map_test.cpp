// Normal maps, bump maps, tangent frames and one-sided surfaces. Exact answers: a flat normal map
// changes no bit of an image; a Lambertian surface whose shading normal is tilted by theta, under
// a uniform sky of radiance 1, reflects albedo * (1 + cos theta) / 2
// (tests/renderer/shading_test.cpp); a height that rises linearly along u tilts the normal by
// atan(slope / |dp/du|).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/image/png.h"
#include "tests/renderer/surface_scenes.h"
#include "renderer/surface_shading.h"

namespace rayfarm {
namespace {

using testing::quad_at;
using testing::render_pixels;
using testing::scene_from;

constexpr double kPiD = 3.14159265358979323846;

/// A diffuse quad (albedo 0.5) facing a perspective camera on +z, under a uniform sky, with the
/// material's extra keys `extra` and the textures `textures`.
Scene quad_under_sky(testing::TempDir& dir, const std::string& textures, const std::string& extra,
                     const std::string& render = R"("integrator": "naive", "max_depth": 1)") {
  return scene_from(dir, R"(
    "camera": {"eye": [0, 0, 2], "look_at": [0, 0, 0], "fov_y": 20},
    "film": {"width": 8, "height": 8},
    "textures": {)" + textures +
                             R"(},
    "materials": {"m": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5])" +
                             extra + R"(}},
    "shapes": [)" + quad_at(0.f, "m") +
                             R"(],
    "background": [1, 1, 1],
    "render": {)" + render + "}");
}

/// A constant tangent-space normal (x, y, z) as a checkerboard of one colour, encoded in [0, 1].
std::string constant_normal_texture(double x, double y, double z) {
  const std::string c = "[" + std::to_string((x + 1) / 2) + ", " + std::to_string((y + 1) / 2) +
                        ", " + std::to_string((z + 1) / 2) + "]";
  return R"("n": {"type": "checkerboard", "color0": )" + c + R"(, "color1": )" + c + "}";
}

TEST(NormalMapTest, AFlatMapRendersExactlyAsNone) {
  testing::TempDir dir;
  // MIS with a point light and several bounces: every random number is used as without a map.
  const std::string render = R"("integrator": "mis", "max_depth": 4)";
  Scene plain = quad_under_sky(dir, constant_normal_texture(0, 0, 1), "", render);
  Scene mapped = quad_under_sky(dir, constant_normal_texture(0, 0, 1),
                                R"(, "normal_map": {"texture": "n"})", render);
  for (Scene* s : {&plain, &mapped}) s->point_lights.push_back({{0.3f, 0.4f, 1.f}, Vec3(2.f)});
  ASSERT_TRUE(mapped.materials[0].normal_map);
  const auto a = render_pixels(plain, 16, IntegratorType::kMis);
  const auto b = render_pixels(mapped, 16, IntegratorType::kMis);
  EXPECT_EQ(a.total, b.total);
  EXPECT_EQ(a.total_sq, b.total_sq);
  for (size_t p = 0; p < a.mean.size(); ++p) EXPECT_EQ(a.mean[p], b.mean[p]) << "pixel " << p;
}

TEST(NormalMapTest, ATiltedMapReflectsTheClippedCosineShareOfTheSky) {
  // Three tilts and a scaled one, one comparison each: 5 standard errors keep the chance of a
  // false alarm below 4 * 6e-7.
  struct Case {
    double tilt_deg, scale;
  };
  for (const Case c : {Case{20, 1}, Case{45, 1}, Case{70, 1}, Case{45, 0.5}}) {
    testing::TempDir dir;
    const double t = c.tilt_deg * kPiD / 180.0;
    const Scene s = quad_under_sky(
        dir, constant_normal_texture(std::sin(t), 0, std::cos(t)),
        R"(, "normal_map": {"texture": "n", "scale": )" + std::to_string(c.scale) + "}");
    // The scale shortens x and y: the tilt becomes atan(scale tan t).
    const double tilt = std::atan(c.scale * std::tan(t));
    const auto r = render_pixels(s, 512, IntegratorType::kNaive);
    const double expected = 0.5 * (1.0 + std::cos(tilt)) / 2.0;
    EXPECT_NEAR(r.image_mean(), expected, 5.0 * r.standard_error() + 1e-6)
        << "tilt " << c.tilt_deg << " scale " << c.scale;
    EXPECT_LT(r.standard_error(), 0.01 * expected) << "too few samples for a meaningful test";
  }
}

/// The shading normal and frame where a ray straight down -z meets the scene at (x, y).
struct Shaded {
  SurfaceHit hit;
  Frame frame{Vec3(0.f, 0.f, 1.f)};
};
Shaded shade_at(const SceneData& data, float x, float y) {
  const Ray ray{{x, y, 5.f}, {0.f, 0.f, -1.f}};
  const auto rh = data.bvh().intersect(ray);
  EXPECT_TRUE(rh);
  Shaded out;
  if (!rh) return out;
  out.hit = data.resolve(ray, *rh);
  out.frame = shade_surface(data, *rh, out.hit);
  return out;
}

TEST(NormalMapTest, TheTiltFollowsTheTangentAndTheBitangentIsTheImagesUp) {
  testing::TempDir dir;
  // +x in tangent space is +u = +x in the world, +y is the image's up = +v = +y.
  for (const auto& [local, want] : {std::pair{Vec3(0.6f, 0.f, 0.8f), Vec3(0.6f, 0.f, 0.8f)},
                                    std::pair{Vec3(0.f, 0.6f, 0.8f), Vec3(0.f, 0.6f, 0.8f)}}) {
    const Scene s = quad_under_sky(dir, constant_normal_texture(local.x, local.y, local.z),
                                   R"(, "normal_map": {"texture": "n"})");
    const SceneData data(s);
    const Vec3 ns = shade_at(data, 0.3f, -0.2f).hit.ns;
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(ns[i], want[i], 1e-5f) << i;
  }
}

TEST(BumpMapTest, ALinearRampTiltsTheNormalByItsSlope) {
  testing::TempDir dir;
  // 256 texels rising by 1/255 each: read linear and bilinear, the height rises by 256/255 per
  // unit of u between the first and last texel centres.
  std::vector<uint8_t> ramp;
  for (int i = 0; i < 256; ++i) ramp.insert(ramp.end(), {uint8_t(i), uint8_t(i), uint8_t(i)});
  write_png_rgb8(dir.path() / "ramp.png", ramp, 256, 1);
  for (const double scale : {0.5, 2.0}) {
    const Scene s =
        quad_under_sky(dir, R"("h": {"type": "image", "file": "ramp.png"})",
                       R"(, "bump_map": {"texture": "h", "scale": )" + std::to_string(scale) + "}");
    ASSERT_EQ(s.textures[0].space, ColourSpace::linear) << "a height map is read linear";
    const SceneData data(s);
    // dp/du is 2 units long: the surface rises by scale * 256/255 / 2 per unit of x.
    const double slope = scale * (256.0 / 255.0) / 2.0;
    const double tilt = std::atan(slope);
    for (const float x : {-0.5f, 0.1f, 0.6f}) {
      const Vec3 ns = shade_at(data, x, 0.25f).hit.ns;
      EXPECT_NEAR(ns.x, -std::sin(tilt), 2e-4) << "scale " << scale << " at x " << x;
      EXPECT_NEAR(ns.y, 0.0, 1e-6);
      EXPECT_NEAR(ns.z, std::cos(tilt), 2e-4);
    }
  }
}

TEST(TangentFrameTest, AnisotropicFramesFollowTheTangent) {
  testing::TempDir dir;
  // The quad's edge1 runs along x + y: dp/du, and so the frame's first axis, does too.
  const Scene s = scene_from(dir, R"(
    "camera": {"eye": [0, 0, 2], "look_at": [0, 0, 0], "fov_y": 20},
    "film": {"width": 4, "height": 4},
    "materials": {"a": {"type": "roughconductor", "alpha_u": 0.1, "alpha_v": 0.4},
                  "i": {"type": "roughconductor", "alpha": 0.2}},
    "shapes": [{"type": "quad", "corner": [-1, 0, 0], "edge1": [1, 1, 0], "edge2": [1, -1, 0],
                "material": "a"},
               {"type": "quad", "corner": [5, 0, 0], "edge1": [1, 1, 0], "edge2": [1, -1, 0],
                "material": "i"}])");
  const SceneData data(s);
  EXPECT_TRUE(data.uses_surface());
  const Shaded a = shade_at(data, 0.1f, 0.05f);
  const float h = std::sqrt(0.5f);
  EXPECT_NEAR(a.frame.s.x, h, 1e-6f);
  EXPECT_NEAR(a.frame.s.y, h, 1e-6f);
  EXPECT_NEAR(dot(cross(a.frame.s, a.frame.t), a.frame.n), 1.f, 1e-6f) << "right-handed";
  // An isotropic one keeps the frame of its normal alone.
  const Shaded i = shade_at(data, 6.f, 0.05f);
  const Frame plain(i.hit.ns);
  EXPECT_EQ(i.frame.s, plain.s);

  // A mesh's own tangents win over the texture coordinates.
  Scene with_tangents = s;
  with_tangents.meshes[0].tangents.assign(4, Vec4(0.f, 1.f, 0.f, 1.f));
  const SceneData data2(with_tangents);
  const Shaded t = shade_at(data2, 0.1f, 0.05f);
  EXPECT_NEAR(t.frame.s.y, 1.f, 1e-6f);
}

TEST(OneSidedTest, BothSidesReflectUnlessOneSidedAndTwosidedIsTheIdentity) {
  testing::TempDir dir;
  // The camera looks at the quad's back (the quad faces -z): diffuse reflects there too, unless
  // one_sided; the front is unchanged by it.
  const auto render_side = [&](const std::string& material, float camera_z) {
    const Scene s = scene_from(dir, R"(
      "camera": {"eye": [0, 0, )" + std::to_string(camera_z) +
                                        R"(], "look_at": [0, 0, 0], "fov_y": 20},
      "film": {"width": 4, "height": 4},
      "materials": {"m": )" + material + R"(},
      "shapes": [{"type": "quad", "corner": [-1, -1, 0], "edge1": [0, 2, 0], "edge2": [2, 0, 0],
                  "material": "m"}],
      "background": [1, 1, 1],
      "render": {"integrator": "naive", "max_depth": 1})");
    return render_pixels(s, 4, IntegratorType::kNaive).image_mean();
  };
  // Albedo 1: Russian roulette always survives, so every sample is exactly 1 or 0.
  const std::string diffuse = R"({"type": "diffuse", "albedo": [1, 1, 1]})";
  const std::string one_sided = R"({"type": "diffuse", "albedo": [1, 1, 1], "one_sided": true})";
  EXPECT_NEAR(render_side(diffuse, 3.f), 1.0, 1e-6) << "the back reflects by default";
  EXPECT_EQ(render_side(one_sided, 3.f), 0.0) << "a one-sided back is black";
  EXPECT_NEAR(render_side(one_sided, -3.f), 1.0, 1e-6) << "a one-sided front reflects";
  EXPECT_NEAR(render_side(R"({"type": "twosided", "material": )" + one_sided + "}", 3.f), 1.0, 1e-6)
      << "twosided makes both sides reflect";
}

TEST(SurfaceFormatTest, BadSurfaceKeysFailNamingThePlace) {
  testing::TempDir dir;
  const auto error_of = [&](const std::string& textures, const std::string& material) {
    try {
      scene_from(dir, R"(
        "camera": {"eye": [0, 0, 2], "look_at": [0, 0, 0], "fov_y": 20},
        "film": {"width": 4, "height": 4},
        "textures": {)" + textures +
                          R"(},
        "materials": {"m": )" +
                          material + "}");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  write_png_rgb8(dir.path() / "n.png", {128, 128, 255}, 1, 1);
  const std::string srgb = R"("n": {"type": "image", "file": "n.png", "color_space": "srgb"})";
  EXPECT_NE(error_of(srgb, R"({"type": "diffuse", "normal_map": {"texture": "n"}})")
                .find("/materials/m/normal_map/texture"),
            std::string::npos)
      << error_of(srgb, R"({"type": "diffuse", "normal_map": {"texture": "n"}})");
  EXPECT_NE(error_of("", R"({"type": "dielectric", "one_sided": true})").find("opaque"),
            std::string::npos);
  EXPECT_NE(
      error_of("", R"({"type": "diffuse", "emission": [1, 1, 1], "opacity": 0})").find("cut-outs"),
      std::string::npos);
  EXPECT_NE(error_of("", R"({"type": "diffuse", "alpha_cutoff": 2})").find("alpha_cutoff"),
            std::string::npos);
}

TEST(SurfaceFormatTest, ThePlanNamesTheSurfaceFeatures) {
  testing::TempDir dir;
  const Scene plain = quad_under_sky(dir, constant_normal_texture(0, 0, 1), "");
  EXPECT_NE(Renderer(plain, plain.render).plan().find("surfaces: plain"), std::string::npos);
  const Scene mapped =
      quad_under_sky(dir, constant_normal_texture(0, 0, 1), R"(, "normal_map": {"texture": "n"})");
  const std::string plan = Renderer(mapped, mapped.render).plan();
  EXPECT_NE(plan.find("1 normal-mapped"), std::string::npos) << plan;
  EXPECT_NE(plan.find("tangents from UVs"), std::string::npos) << plan;
}

}  // namespace
}  // namespace rayfarm
