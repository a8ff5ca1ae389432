// The Mitsuba 3 XML reader (docs/mitsuba.md): what each plugin becomes in rayfarm's scene, the
// XML layer (includes, defaults, $name), and every kind of bad input naming its file and line.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <variant>

#include "common/bundle/bundle.h"
#include "common/scene/mitsuba_loader.h"
#include "common/scene/spectra.h"
#include "tests/support/image_writers.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;

const char* kSensor = R"(
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="30"/><integer name="height" value="20"/>
      <rfilter type="box"/></film>
    <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
  </sensor>)";

/// A scene file holding kSensor and `body`.
std::string scene(const std::string& body, const std::string& version = "3.0.0") {
  return "<scene version=\"" + version + "\">" + kSensor + body + "\n</scene>\n";
}

const char* kQuad =
    "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
    "f 1/1 2/2 3/3 4/4\n";

class MitsubaLoader : public ::testing::Test {
 protected:
  Scene load(const std::string& body, const XmlParameters& parameters = {}) {
    dir_.write("quad.obj", kQuad);
    return load_mitsuba_scene(dir_.write("s.xml", scene(body)), {}, SceneImages::kCheckOnly, {},
                              parameters);
  }
  /// Expects loading `xml` (the whole file) to fail with a message holding each of `parts`.
  void expect_error(const std::string& xml, std::initializer_list<const char*> parts,
                    const fs::path& root = {}) {
    dir_.write("quad.obj", kQuad);
    const fs::path file = dir_.write("sub/s.xml", xml);
    try {
      (void)load_mitsuba_scene(file, {}, SceneImages::kCheckOnly, root);
      ADD_FAILURE() << "loaded:\n" << xml;
    } catch (const SceneError& e) {
      for (const char* part : parts)
        EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  }
  testing::TempDir dir_;
};

// The bundled Mitsuba scene (scenes/mitsuba-spheres) loads without a warning, as written, and
// its $spp parameter is the sample count.
TEST(MitsubaBundled, TheSpheresSceneLoadsAsWritten) {
  const fs::path file =
      fs::path(RAYFARM_SOURCE_DIR) / "scenes" / "mitsuba-spheres" / "scene.xml";
  const Scene scene = load_mitsuba_scene(file, {}, SceneImages::kCheckOnly, {}, {});
  std::string warnings;
  for (const std::string& w : scene.warnings) warnings += w + "\n";
  EXPECT_TRUE(scene.warnings.empty()) << warnings;
  EXPECT_EQ(scene.film.width, 320u);
  EXPECT_EQ(scene.film.height, 200u);
  EXPECT_EQ(scene.render.spp, 64u);
  EXPECT_EQ(scene.spheres.size(), 3u);
  size_t emissive = 0;
  for (const Material& m : scene.materials) emissive += m.is_emissive() ? 1 : 0;
  EXPECT_EQ(emissive, 1u) << "the square light";
  const Scene more = load_mitsuba_scene(file, {}, SceneImages::kCheckOnly, {}, {{"spp", "8"}});
  EXPECT_EQ(more.render.spp, 8u);
}

TEST_F(MitsubaLoader, SensorFilmAndSamplerBecomeTheCameraFilmAndSampleCount) {
  const Scene s = load("");
  EXPECT_EQ(s.film.width, 30u);
  EXPECT_EQ(s.film.height, 20u);
  EXPECT_EQ(s.render.spp, 16u);
  EXPECT_EQ(s.camera.eye.z, 5.f);
  EXPECT_EQ(s.camera.look_at.z, 4.f);
  // fov is horizontal (fov_axis x): the vertical one follows from the 3:2 aspect ratio.
  const double fy = 2.0 * std::atan(std::tan(20.0 * kPi / 180.0) / 1.5) * 180.0 / kPi;
  EXPECT_NEAR(s.camera.fov_y_deg, fy, 1e-4);
  EXPECT_EQ(s.render.max_depth, kUnlimitedDepth);  // no integrator: Mitsuba's unlimited path tracer
}

// The reconstruction filter with Mitsuba's defaults: none named is its Gaussian (stddev 0.5,
// radius 4 stddev), and only the image is sampled unless the film says sample_border.
TEST_F(MitsubaLoader, FiltersHaveMitsubasDefaults) {
  const auto filter = [&](const std::string& film) {
    dir_.write("quad.obj", kQuad);
    const std::string xml = R"(<scene version="3.0.0"><sensor type="perspective">
      <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>)" +
                            film + "</film></sensor></scene>";
    const Scene scene =
        load_mitsuba_scene(dir_.write("f.xml", xml), {}, SceneImages::kCheckOnly, {}, {});
    for (const std::string& w : scene.warnings) EXPECT_EQ(w.find("filter"), std::string::npos) << w;
    return scene.filter;
  };
  const PixelFilter none = filter("");
  EXPECT_EQ(none.type, FilterType::kGaussian);
  EXPECT_EQ(none.stddev, 0.5f);
  EXPECT_EQ(none.radius, 2.f);
  EXPECT_FALSE(none.sample_border);
  EXPECT_EQ(none.steps, 31u) << "tabulated as Mitsuba's scalar variants tabulate it";
  EXPECT_TRUE(filter(R"(<rfilter type="box"/>)").pixel_box());
  EXPECT_TRUE(filter(R"(<boolean name="sample_border" value="true"/>)").sample_border);
  EXPECT_EQ(
      filter(R"(<rfilter type="gaussian"><float name="stddev" value="0.25"/></rfilter>)").radius,
      1.f);
  const PixelFilter tent = filter(R"(<rfilter type="tent"/>)");
  EXPECT_EQ(tent.type, FilterType::kTent);
  EXPECT_EQ(tent.radius, 1.f);
  EXPECT_EQ(filter(R"(<rfilter type="tent"><float name="radius" value="1.5"/></rfilter>)").radius,
            1.5f);
  const PixelFilter mitchell = filter(R"(<rfilter type="mitchell"/>)");
  EXPECT_EQ(mitchell.type, FilterType::kMitchell);
  EXPECT_EQ(mitchell.b, 1.f / 3.f);
  EXPECT_EQ(mitchell.c, 1.f / 3.f);
  EXPECT_EQ(mitchell.radius, 2.f);
  const PixelFilter catmull = filter(R"(<rfilter type="catmullrom"/>)");
  EXPECT_EQ(catmull.b, 0.f);
  EXPECT_EQ(catmull.c, 0.5f);
  const PixelFilter lanczos = filter(R"(<rfilter type="lanczos"/>)");
  EXPECT_EQ(lanczos.type, FilterType::kLanczos);
  EXPECT_EQ(lanczos.steps, 31u);
  EXPECT_EQ(lanczos.radius, 3.f);
  EXPECT_EQ(filter(R"(<rfilter type="lanczos"><integer name="lobes" value="2"/></rfilter>)").radius,
            2.f);
  const std::string film =
      R"(<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm">)";
  expect_error(film + R"(<rfilter type="sinc"/></film></sensor></scene>)",
               {"s.xml:1:", "<rfilter type=\"sinc\">", "not supported", "lanczos"});
  expect_error(film + R"(<rfilter type="tent"><float name="radius" value="0"/></rfilter>)"
                      "</film></sensor></scene>",
               {"radius must lie in [0.001, 8]"});
  expect_error(film + R"(<rfilter type="box"><float name="radius" value="2"/></rfilter>)"
                      "</film></sensor></scene>",
               {"\"radius\""});
}

TEST_F(MitsubaLoader, DepthCountsSegmentsInMitsubaAndScatteringVerticesHere) {
  auto depth = [&](const std::string& integrator) {
    return load(integrator + "<shape type=\"sphere\"/>").render.max_depth;
  };
  EXPECT_EQ(depth(R"(<integrator type="path"><integer name="max_depth" value="2"/></integrator>)"),
            1u);
  EXPECT_EQ(depth(R"(<integrator type="path"><integer name="max_depth" value="8"/></integrator>)"),
            7u);
  EXPECT_EQ(depth(R"(<integrator type="moment"><integrator type="path">
      <integer name="max_depth" value="1"/></integrator></integrator>)"),
            0u);
  EXPECT_EQ(depth(R"(<integrator type="direct"/>)"), 1u);
  expect_error(
      scene(R"(<integrator type="path"><integer name="max_depth" value="0"/></integrator>)"),
      {"s.xml:", "max_depth 0 renders nothing"});
}

// Integrators that converge to the path tracer's image are rendered by it, with a warning and
// their depths; one that renders something else (aov) is refused.
TEST_F(MitsubaLoader, OtherEstimatorsOfTheSameImageAreRenderedByThePathTracer) {
  for (const char* type : {"ptracer", "bdpt", "prb"}) {
    const Scene s = load(std::string(R"(<integrator type=")") + type +
                         R"("><integer name="max_depth" value="4"/></integrator>)");
    EXPECT_EQ(s.render.max_depth, 3u) << type;
    std::string all;
    for (const std::string& w : s.warnings) all += w + "\n";
    EXPECT_NE(all.find(std::string("same image as \"") + type + "\""), std::string::npos) << all;
  }
  expect_error(scene(R"(<integrator type="aov"/>)"),
               {"<integrator type=\"aov\">", "not supported"});
}

TEST_F(MitsubaLoader, BsdfsBecomeMaterialsWithMitsubasDefaultsAndSides) {
  const Scene s = load(R"(
    <bsdf type="diffuse" id="d"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf>
    <shape type="sphere"><ref id="d"/></shape>
    <shape type="sphere"><bsdf type="twosided"><ref id="d"/></bsdf></shape>
    <shape type="sphere"><bsdf type="roughconductor"><string name="material" value="Au"/>
      <float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.05"/></bsdf></shape>
    <shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="diamond"/></bsdf></shape>
    <shape type="sphere"><bsdf type="roughplastic"><string name="distribution" value="ggx"/>
      <boolean name="nonlinear" value="true"/></bsdf></shape>
    <shape type="sphere"/>)");
  ASSERT_EQ(s.spheres.size(), 6u);
  auto mat = [&](int i) -> const Material& { return s.materials[s.spheres[i].material]; };
  EXPECT_TRUE(mat(0).one_sided);  // Mitsuba's BSDFs are black from behind
  EXPECT_FALSE(mat(1).one_sided);
  EXPECT_EQ(std::get<DiffuseMaterial>(mat(1).kind).albedo.value, Vec3(0.2f, 0.4f, 0.6f));
  const auto& au = std::get<RoughConductorMaterial>(mat(2).kind);
  EXPECT_EQ(au.distribution, MicrofacetType::kBeckmann);  // Mitsuba's default
  EXPECT_EQ(au.alpha_u.value, 0.2f);
  EXPECT_EQ(au.alpha_v.value, 0.05f);
  EXPECT_EQ(au.eta, named_conductor("Au")->eta);
  const auto& glass = std::get<DielectricMaterial>(mat(3).kind);
  EXPECT_NEAR(glass.ior, 2.419 / 1.000277, 1e-5);  // over Mitsuba's default exterior, air
  EXPECT_FALSE(mat(3).one_sided);
  const auto& plastic = std::get<PlasticMaterial>(mat(4).kind);
  EXPECT_EQ(plastic.distribution, MicrofacetType::kGgx);
  EXPECT_TRUE(plastic.nonlinear);
  EXPECT_EQ(plastic.alpha.value, 0.1f);
  EXPECT_NEAR(plastic.ior, 1.49 / 1.000277, 1e-5);
  EXPECT_EQ(std::get<DiffuseMaterial>(mat(5).kind).albedo.value, Vec3(0.5f));  // the default
}

TEST_F(MitsubaLoader, SpectraAreConvertedAsMitsubasRgbModeDoes) {
  const Scene s = load(R"(<shape type="sphere"><bsdf type="diffuse">
    <spectrum name="reflectance" value="400:0.78, 500:0.78, 600:0.78, 700:0.78"/></bsdf></shape>)");
  const Vec3 expected =
      spectrum_to_rgb({400, 500, 600, 700}, {0.78, 0.78, 0.78, 0.78}, SpectrumRole::reflectance);
  EXPECT_EQ(std::get<DiffuseMaterial>(s.materials[s.spheres[0].material].kind).albedo.value,
            expected);
  EXPECT_LT(expected.x, 0.78f);  // nothing below 400 nm or above 700 nm
}

TEST_F(MitsubaLoader, ShapesMasksAndMapsBecomeGeometryAndSurfaceProperties) {
  const Scene s = load(R"(
    <shape type="obj"><string name="filename" value="quad.obj"/>
      <transform name="to_world"><scale value="2"/><translate x="1"/></transform></shape>
    <shape type="rectangle"><boolean name="flip_normals" value="true"/></shape>
    <shape type="cube"/>
    <shape type="disk"/>
    <shape type="obj"><string name="filename" value="quad.obj"/>
      <boolean name="face_normals" value="true"/>
      <bsdf type="mask"><float name="opacity" value="0.25"/><bsdf type="diffuse"/></bsdf></shape>)");
  ASSERT_EQ(s.meshes.size(), 5u);
  EXPECT_EQ(s.meshes[0].positions[1].x, 3.f);  // (1, -1, 0) scaled by 2, then moved by 1
  EXPECT_FALSE(s.meshes[0].normals.empty());   // Mitsuba smooths a mesh without normals
  EXPECT_EQ(s.meshes[0].normals[0], Vec3(0.f, 0.f, 1.f));
  EXPECT_EQ(s.meshes[1].normals[0], Vec3(0.f, 0.f, -1.f));
  EXPECT_EQ(s.meshes[2].triangle_count(), 12u);
  double area = 0.0;
  for (size_t t = 0; t < s.meshes[3].triangle_count(); ++t) {
    const uint32_t* i = &s.meshes[3].indices[3 * t];
    area += 0.5 * length(cross(s.meshes[3].positions[i[1]] - s.meshes[3].positions[i[0]],
                               s.meshes[3].positions[i[2]] - s.meshes[3].positions[i[0]]));
  }
  EXPECT_NEAR(area, kPi, 1e-4 * kPi);  // the unit disk
  EXPECT_TRUE(s.meshes[4].normals.empty());
  const Material& masked = s.materials[s.meshes[4].materials[0]];
  EXPECT_TRUE(masked.alpha_blend);  // partly there: Mitsuba's mask is a probability
  EXPECT_EQ(masked.alpha.value, 0.25f);
  EXPECT_TRUE(masked.has_alpha());
}

// Mitsuba's cube: each face's texture coordinates laid out as Mitsuba lays them (on +z, u runs
// along +y and v along +x; on -y, u along +z and v along +x), every triangle facing out.
TEST_F(MitsubaLoader, ACubeHasMitsubasFaceLayout) {
  const Scene s = load(R"(<shape type="cube"/>)");
  ASSERT_EQ(s.meshes.size(), 1u);
  const TriangleMesh& m = s.meshes[0];
  ASSERT_EQ(m.triangle_count(), 12u);
  ASSERT_EQ(m.uvs.size(), m.positions.size());
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    const Vec3 &a = m.positions[m.indices[3 * t]], &b = m.positions[m.indices[3 * t + 1]],
               &c = m.positions[m.indices[3 * t + 2]];
    const Vec3 centre = (a + b + c) / 3.f;
    EXPECT_GT(dot(cross(b - a, c - a), centre), 0.f) << "triangle " << t << " faces in";
  }
  size_t on_z = 0, on_minus_y = 0;
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const Vec3& p = m.positions[i];
    const Vec2 uv = m.uvs[i];
    if (m.normals[i] == Vec3(0.f, 0.f, 1.f)) {
      EXPECT_EQ(uv, (Vec2{(p.y + 1.f) / 2.f, (p.x + 1.f) / 2.f})) << i;
      ++on_z;
    }
    if (m.normals[i] == Vec3(0.f, -1.f, 0.f)) {
      EXPECT_EQ(uv, (Vec2{(p.z + 1.f) / 2.f, (p.x + 1.f) / 2.f})) << i;
      ++on_minus_y;
    }
  }
  EXPECT_EQ(on_z, 4u);
  EXPECT_EQ(on_minus_y, 4u);
}

// Mitsuba flips v on reading an OBJ file, not a PLY file (flip_tex_coords defaults to true for
// obj, false for ply): a textured material is converted once per kind of coordinates, so a PLY
// with the default shares the texture of a built-in shape, and one flipped that of the OBJ.
TEST_F(MitsubaLoader, TextureCoordinatesAreFlippedForObjFilesOnly) {
  dir_.write("tri.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "property float z\nproperty float u\nproperty float v\nelement face 1\n"
             "property list uchar int vertex_indices\nend_header\n"
             "0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n");
  const std::string bsdf = R"(<bsdf type="diffuse" id="checks"><texture name="reflectance"
      type="checkerboard"><transform name="to_uv"><scale value="4"/></transform></texture></bsdf>)";
  const auto textures_for = [&](const std::string& ply_flip) {
    return load(bsdf + R"(
      <shape type="obj"><string name="filename" value="quad.obj"/><ref id="checks"/></shape>
      <shape type="ply"><string name="filename" value="tri.ply"/>)" +
                ply_flip + R"(<ref id="checks"/></shape>
      <shape type="rectangle"><ref id="checks"/></shape>)")
        .textures.size();
  };
  EXPECT_EQ(textures_for(""), 2u) << "the PLY's coordinates are Mitsuba's own, as a rectangle's";
  EXPECT_EQ(textures_for(R"(<boolean name="flip_tex_coords" value="true"/>)"), 2u);
  EXPECT_EQ(textures_for(R"(<boolean name="flip_tex_coords" value="false"/>)"), 2u);
  const Scene flipped = load(bsdf + R"(
      <shape type="obj"><string name="filename" value="quad.obj"/><ref id="checks"/></shape>
      <shape type="ply"><string name="filename" value="tri.ply"/>
        <boolean name="flip_tex_coords" value="true"/><ref id="checks"/></shape>)");
  EXPECT_EQ(flipped.textures.size(), 1u) << "both flipped: one texture";
  const Scene plain = load(bsdf + R"(
      <shape type="ply"><string name="filename" value="tri.ply"/><ref id="checks"/></shape>
      <shape type="rectangle"><ref id="checks"/></shape>)");
  EXPECT_EQ(plain.textures.size(), 1u) << "neither flipped: one texture";
}

// A <lookat> without an up takes Mitsuba's: the first vector of the basis it builds around the
// view direction (+x looking along -z or straight down), where rayfarm's own default (+y) would
// roll the image or be parallel to the view.
TEST_F(MitsubaLoader, ALookatWithoutUpTakesMitsubasBasis) {
  const auto camera_of = [&](const std::string& lookat) {
    const std::string xml = R"(<scene version="3.0.0"><sensor type="perspective">
      <transform name="to_world">)" +
                            lookat + R"(</transform></sensor></scene>)";
    return load_mitsuba_scene(dir_.write("c.xml", xml), {}, SceneImages::kCheckOnly, {}, {}).camera;
  };
  EXPECT_EQ(camera_of(R"(<lookat origin="0, 0, 5" target="0, 0, 0"/>)").up, Vec3(1.f, 0.f, 0.f));
  EXPECT_EQ(camera_of(R"(<lookat origin="0, 5, 0" target="0, 0, 0"/>)").up, Vec3(1.f, 0.f, 0.f));
  EXPECT_EQ(camera_of(R"(<lookat origin="0, 0, 0" target="0, 0, 1" up="0, 0, 0"/>)").up,
            Vec3(1.f, 0.f, 0.f));
  // Along +x: n = (1, 0, 0), sign +1, a = -1: up = (1 - 1, 0, -1) = (0, 0, -1).
  const Vec3 up = camera_of(R"(<lookat origin="0, 0, 0" target="3, 0, 0"/>)").up;
  EXPECT_NEAR(up.x, 0.f, 1e-7f);
  EXPECT_EQ(up.z, -1.f);
  EXPECT_EQ(camera_of(R"(<lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>)").up,
            Vec3(0.f, 1.f, 0.f));
}

// A shapegroup's meshes are instanced; its spheres become spheres of the scene, one per
// instance, placed by the instance's transform (which must keep them round).
TEST_F(MitsubaLoader, ShapegroupsPlaceTheirSpheresAtEveryInstance) {
  const Scene s = load(R"(
    <shape type="shapegroup" id="g">
      <shape type="sphere"><float name="radius" value="0.5"/>
        <point name="center" x="1" y="0" z="0"/></shape>
      <shape type="obj"><string name="filename" value="quad.obj"/></shape>
    </shape>
    <shape type="instance"><ref id="g"/></shape>
    <shape type="instance"><ref id="g"/>
      <transform name="to_world"><scale value="2"/><translate x="10"/></transform></shape>
    <shape type="shapegroup" id="balls"><shape type="sphere"/></shape>
    <shape type="instance"><ref id="balls"/>
      <transform name="to_world"><translate y="-3"/></transform></shape>)");
  ASSERT_EQ(s.spheres.size(), 3u);
  EXPECT_EQ(s.spheres[0].center, Vec3(1.f, 0.f, 0.f));
  EXPECT_EQ(s.spheres[0].radius, 0.5f);
  EXPECT_EQ(s.spheres[1].center, Vec3(12.f, 0.f, 0.f));  // scaled by 2, then moved by 10
  EXPECT_EQ(s.spheres[1].radius, 1.f);
  EXPECT_EQ(s.spheres[2].center, Vec3(0.f, -3.f, 0.f));
  EXPECT_EQ(s.instances.size(), 2u) << "the spheres-only group places no mesh instance";
  EXPECT_TRUE(s.meshes.empty());
  expect_error(scene(R"(<shape type="shapegroup" id="g"><shape type="sphere"/></shape>
    <shape type="instance"><ref id="g"/>
      <transform name="to_world"><scale x="2"/></transform></shape>)"),
               {"<shape type=\"instance\">", "scale all directions alike"});
}

// A projector is a spot that casts its irradiance image through a camera's frustum (Mitsuba's
// sample space: u = 0.5 - 0.5 x / (z tan(fov_x / 2)), v = 0.5 - 0.5 aspect y / (z tan)), its
// aspect ratio the image's; a spot's texture is cast at u = 0.5 + 0.5 x / (z tan(cutoff)).
TEST_F(MitsubaLoader, ProjectorsAndTexturedSpotsCastTheirImages) {
  testing::PngSpec png;
  png.width = 4;
  png.height = 2;
  png.samples.assign(4 * 2 * 3, 200);
  const testing::Bytes bytes = testing::encode_png(png);
  dir_.write("wide.png", std::string(bytes.begin(), bytes.end()));
  const Scene s = load(R"(
    <emitter type="projector"><float name="fov" value="90"/><float name="scale" value="2"/>
      <transform name="to_world"><lookat origin="0, 3, 0" target="0, 0, 0" up="0, 0, 1"/>
      </transform></emitter>
    <emitter type="projector"><float name="fov" value="90"/>
      <texture type="bitmap" name="irradiance"><string name="filename" value="wide.png"/></texture>
    </emitter>
    <emitter type="spot"><float name="cutoff_angle" value="30"/>
      <texture type="bitmap" name="texture"><string name="filename" value="wide.png"/></texture>
    </emitter>
    <emitter type="spot"/>)");
  ASSERT_EQ(s.spot_lights.size(), 4u);
  const SpotLight& constant = s.spot_lights[0];
  ASSERT_TRUE(constant.image.has_value());
  EXPECT_TRUE(constant.image->projector);
  EXPECT_FALSE(constant.image->image.is_textured());
  EXPECT_EQ(constant.image->image.value, Vec3(1.f));
  EXPECT_NEAR(constant.image->u_scale, -0.5f, 1e-6f);
  EXPECT_NEAR(constant.image->v_scale, -0.5f, 1e-6f);
  EXPECT_EQ(constant.direction, Vec3(0.f, -1.f, 0.f));
  EXPECT_NEAR(constant.intensity.y, 2.0 * kPi * 0.99971, 1e-5) << "pi x scale x Mitsuba's white";
  EXPECT_NEAR(constant.cutoff_deg, std::atan(std::sqrt(2.0)) * 180.0 / kPi, 1e-4)
      << "the cone through the frustum's corners";
  const SpotLight& wide = s.spot_lights[1];
  ASSERT_TRUE(wide.image.has_value());
  EXPECT_TRUE(wide.image->image.is_textured());
  EXPECT_NEAR(wide.image->u_scale, -0.5f, 1e-6f);
  EXPECT_NEAR(wide.image->v_scale, -1.f, 1e-6f) << "aspect 2, from the image (loaded to check)";
  const SpotLight& spot = s.spot_lights[2];
  ASSERT_TRUE(spot.image.has_value());
  EXPECT_FALSE(spot.image->projector);
  EXPECT_NEAR(spot.image->u_scale, 0.5 / std::tan(kPi / 6), 1e-6);
  EXPECT_EQ(spot.beam_width_deg, 22.5f) << "3/4 of the cutoff";
  EXPECT_FALSE(s.spot_lights[3].image.has_value());
  // A plain spot may open to 90 degrees; one casting a texture needs less (tan(cutoff)), and
  // its texture must be one (Mitsuba refuses a constant there).
  EXPECT_EQ(load(R"(<emitter type="spot"><float name="cutoff_angle" value="90"/></emitter>)")
                .spot_lights.at(0)
                .cutoff_deg,
            90.f);
  expect_error(scene(R"(<emitter type="spot"><float name="cutoff_angle" value="90"/>
    <texture type="checkerboard" name="texture"/></emitter>)"),
               {"below 90 degrees"});
  expect_error(scene(R"(<emitter type="spot"><rgb name="texture" value="0.5"/></emitter>)"),
               {"must be a texture"});
  expect_error(scene(R"(<emitter type="projector"><float name="fov" value="0.01"/></emitter>)"),
               {"narrower than 0.05 degrees"});
  expect_error(scene(R"(<emitter type="projector"><rgb name="irradiance" value="1, -1, 1"/>
    </emitter>)"),
               {"<rgb name=\"irradiance\"", "must not be negative"});
  expect_error(scene(R"(<emitter type="projector"><transform name="to_world"><scale value="2"/>
    </transform></emitter>)"),
               {"<emitter type=\"projector\">", "rotation and a translation"});
}

TEST_F(MitsubaLoader, AreaEmittersAndLightsKeepMitsubasUnitsAndWhite) {
  const Scene s = load(R"(
    <shape type="rectangle"><emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter></shape>
    <emitter type="point"><point name="position" x="1" y="2" z="3"/><rgb name="intensity" value="5"/></emitter>
    <emitter type="spot"><transform name="to_world"><lookat origin="0,4,0" target="0,0,0" up="0,0,1"/></transform>
      <float name="cutoff_angle" value="30"/></emitter>
    <emitter type="directional"><vector name="direction" value="0, -1, 0"/></emitter>
    <emitter type="constant"><float name="radiance" value="2"/></emitter>)");
  const Material& lamp = s.materials[s.meshes[0].materials[0]];
  EXPECT_EQ(lamp.emission.value, Vec3(2.f, 3.f, 4.f));
  EXPECT_FALSE(lamp.two_sided);
  ASSERT_EQ(s.point_lights.size(), 1u);
  EXPECT_EQ(s.point_lights[0].position, Vec3(1.f, 2.f, 3.f));
  EXPECT_EQ(s.point_lights[0].intensity, Vec3(5.f));
  ASSERT_EQ(s.spot_lights.size(), 1u);
  EXPECT_EQ(s.spot_lights[0].direction, Vec3(0.f, -1.f, 0.f));
  EXPECT_EQ(s.spot_lights[0].beam_width_deg, 22.5f);  // 3/4 of the cutoff
  ASSERT_EQ(s.directional_lights.size(), 1u);
  // Defaults and plain numbers are Mitsuba's white, D65 as its RGB variants see it.
  EXPECT_NEAR(s.directional_lights[0].irradiance.x, 1.00108f, 1e-5f);
  ASSERT_TRUE(s.environment.has_value());
  EXPECT_NEAR(s.environment->scale.x, 2.00216f, 1e-5f);
}

TEST_F(MitsubaLoader, IncludesDefaultsAndParametersAreResolvedInOrder) {
  dir_.write("parts/ball.xml",
             R"(<scene version="3.0.0"><default name="r" value="0.5"/>
                <shape type="sphere"><float name="radius" value="$r"/></shape></scene>)");
  const Scene a = load(R"(<include filename="parts/ball.xml"/>)");
  ASSERT_EQ(a.spheres.size(), 1u);
  EXPECT_EQ(a.spheres[0].radius, 0.5f);
  const Scene b = load(R"(<include filename="parts/ball.xml"/>)", {{"r", "2"}});
  EXPECT_EQ(b.spheres[0].radius, 2.f);  // a value from outside beats the <default>
  const Scene c = load(R"(<default name="r" value="3"/><default name="rr" value="4"/>
      <shape type="sphere"><float name="radius" value="$rr"/></shape>)");
  EXPECT_EQ(c.spheres[0].radius, 4.f);  // the longest name wins
  EXPECT_TRUE(c.referenced.empty());    // the scene file itself is not listed
  ASSERT_EQ(a.referenced.size(), 1u);
  EXPECT_EQ(a.referenced[0], fs::path("parts/ball.xml"));  // an include travels with the scene
}

TEST_F(MitsubaLoader, BadInputNamesTheFileTheLineAndTheElement) {
  expect_error("<scene version=\"3.0.0\"><shape type=\"sphere\"></scene>",
               {"s.xml:1:", "malformed XML"});
  expect_error("<scene><shape type=\"sphere\"/></scene>", {"no version attribute"});
  expect_error(scene("", "0.6.0"), {"version \"0.6.0\"", "2.x and 3.x"});
  expect_error(scene("\n<shape type=\"teapot\"/>"),
               {"s.xml:9: <shape type=\"teapot\">", "not supported"});
  expect_error(scene("\n<shape type=\"sphere\"><string name=\"radius\" value=\"1\"/></shape>"),
               {"s.xml:9: <string name=\"radius\">", "expected a <float>"});
  expect_error(scene("\n<shape type=\"sphere\"><float name=\"radius\" value=\"$big\"/></shape>"),
               {"s.xml:9:", "$big has no value", "-D big=VALUE"});
  expect_error(scene("\n<shape type=\"sphere\"><float name=\"radius\" value=\"1x\"/></shape>"),
               {"s.xml:9:", "not a list of numbers"});
  expect_error(scene("\n<shape type=\"sphere\"><float name=\"shininess\" value=\"1\"/></shape>"),
               {"\"shininess\"", "not supported"});
  expect_error(scene("\n<shape type=\"sphere\"><bsdf type=\"principled\"/></shape>"),
               {"<bsdf type=\"principled\">", "not supported"});
  expect_error(scene("\n<shape type=\"sphere\"><ref id=\"nothing\"/></shape>"),
               {"no element has the id \"nothing\""});
  expect_error(scene("<include filename=\"s.xml\"/>"), {"cycle"});
  expect_error(scene("<include filename=\"missing.xml\"/>"), {"no file missing.xml"});
  expect_error(
      scene("<shape type=\"obj\"><string name=\"filename\" value=\"/etc/passwd\"/></shape>"),
      {"absolute path"});
  expect_error(
      scene("<shape type=\"obj\"><string name=\"filename\" value=\"../quad.obj\"/></shape>"),
      {"lies outside", "--scene-root"});
  expect_error(scene("<path value=\"..\"/>"), {"outside"});
  expect_error(scene("<medium type=\"homogeneous\"/>"), {"<medium", "not supported"});
  dir_.write("sub/bad.png", "not an image");
  expect_error(scene("<shape type=\"sphere\"><bsdf type=\"diffuse\"><texture name=\"reflectance\" "
                     "type=\"bitmap\"><string name=\"filename\" value=\"bad.png\"/></texture>"
                     "</bsdf></shape>"),
               {"s.xml:", "<texture type=\"bitmap\"", "bad.png"});
  expect_error(scene("<emitter type=\"envmap\"><string name=\"filename\" value=\"bad.png\"/>"
                     "</emitter>"),
               {"s.xml:", "<emitter type=\"envmap\">", "bad.png"});
  expect_error(scene("<emitter type=\"area\"/>"), {"belongs inside a <shape>"});
  // Bounds on what a hostile file can make the reader do.
  std::string deep;
  for (int i = 0; i < 70; ++i) deep += "<a>";
  for (int i = 0; i < 70; ++i) deep += "</a>";
  expect_error(scene(deep), {"nest more than 64 deep"});
  expect_error(scene(R"(<integrator type="moment" id="m"><ref id="m"/></integrator>)"),
               {"inside another"});
  expect_error(scene("<shape type=\"sphere\"><float name=\"radius\" value=\"1e300\"/></shape>"),
               {"beyond 1e17"});
  expect_error(
      scene("<default name=\"a\" value=\"$a$a\"/><shape type=\"sphere\">"
            "<float name=\"radius\" value=\"$aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\"/></shape>"),
      {"$a"});
  expect_error(scene("<shape type=\"sphere\"><bsdf type=\"mask\"><bsdf type=\"mask\">"
                     "<bsdf type=\"diffuse\"/></bsdf></bsdf></shape>"),
               {"a mask inside a mask"});
  // Inside the root, what lies above the scene's folder is readable.
  dir_.write("quad.obj", kQuad);
  const fs::path up = dir_.write(
      "sub/up.xml",
      scene("<shape type=\"obj\"><string name=\"filename\" value=\"../quad.obj\"/></shape>"));
  const Scene s = load_mitsuba_scene(up, {}, SceneImages::kCheckOnly, dir_.path());
  ASSERT_EQ(s.referenced.size(), 1u);
  EXPECT_EQ(s.referenced[0], fs::path("../quad.obj"));
}

TEST_F(MitsubaLoader, AParameterMayNameTheFilesTheBundleCarries) {
  dir_.write("a.obj", kQuad);
  dir_.write("b.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const fs::path file = dir_.write(
      "s.xml",
      scene("<shape type=\"obj\"><string name=\"filename\" value=\"$mesh.obj\"/></shape>"));
  const PackedScene packed = pack_mitsuba_scene(file, {}, {{"mesh", "b"}});
  bool has_b = false, has_a = false;
  for (const BundleFile& f : packed.bundle.files)
    has_b |= f.path == "b.obj", has_a |= f.path == "a.obj";
  EXPECT_TRUE(has_b);
  EXPECT_FALSE(has_a);
  testing::TempDir cache;
  const fs::path unpacked = unpack_bundle(packed.bundle, cache.path(), packed.hash);
  const Scene s =
      load_mitsuba_scene(unpacked / packed.scene_path, {}, SceneImages::kCheckOnly, unpacked);
  ASSERT_EQ(s.meshes.size(), 1u);
  EXPECT_EQ(s.meshes[0].triangle_count(), 1u);
}

TEST_F(MitsubaLoader, ABundleCarriesTheFilesAboveTheSceneAndTheParameters) {
  dir_.write("common/quad.obj", kQuad);
  const fs::path file = dir_.write(
      "scenes/a/s.xml", scene("<path value=\"../../common\"/><default name=\"n\" value=\"16\"/>"
                              "<shape type=\"obj\"><string name=\"filename\" value=\"quad.obj\"/>"
                              "<float name=\"unused\" value=\"$n\"/></shape>"));
  EXPECT_THROW(pack_mitsuba_scene(file, dir_.path(), {}), SceneError);  // "unused" is unread
  dir_.write("scenes/a/s.xml",
             scene("<path value=\"../../common\"/><default name=\"n\" value=\"1\"/>"
                   "<shape type=\"obj\"><string name=\"filename\" value=\"quad.obj\"/>"
                   "<transform name=\"to_world\"><scale value=\"$n\"/></transform></shape>"));
  const PackedScene packed = pack_mitsuba_scene(file, dir_.path(), {{"n", "3"}});
  testing::TempDir cache;
  const fs::path unpacked = unpack_bundle(packed.bundle, cache.path(), packed.hash);
  const Scene s =
      load_mitsuba_scene(unpacked / packed.scene_path, {}, SceneImages::kCheckOnly, unpacked);
  ASSERT_EQ(s.meshes.size(), 1u);
  EXPECT_EQ(s.meshes[0].positions[1].x, 3.f);  // -D n=3 travelled with the bundle
}

}  // namespace
}  // namespace rayfarm
