// glTF 2.0 import: what each part of a file becomes in the scene, .gltf and .glb alike, the JSON
// format's "gltf" key, and malformed files (each a SceneError naming the file and the object).
#include <array>
#include <cmath>
#include <cstring>
#include <variant>

#include <gtest/gtest.h>

#include "common/limits.h"
#include "common/scene/parser.h"
#include "tests/support/gltf_builder.h"
#include "tests/support/gltf_load_error.h"
#include "tests/support/image_writers.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

using testing::glb_error;
using testing::GltfBuilder;
using testing::TempDir;
using Json = nlohmann::json;

constexpr double kPi = 3.14159265358979323846;

/// A quad placed by a node (translation, 90 degrees about +y, scale 2), a material, a camera
/// and a point light.
GltfBuilder sample_scene() {
  GltfBuilder b;
  const int material =
      b.push("materials", {{"name", "paint"},
                           {"pbrMetallicRoughness",
                            {{"baseColorFactor", {0.5, 0.25, 0.125, 1.0}},
                             {"metallicFactor", 0.0},
                             {"roughnessFactor", 0.5}}},
                           {"emissiveFactor", {0.0, 0.0, 0.0}},
                           {"extensions", {{"KHR_materials_ior", {{"ior", 1.33}}}}}});
  const int mesh = b.add_quad(material);
  const double s = std::sin(kPi / 4), c = std::cos(kPi / 4);
  b.push("nodes", {{"mesh", mesh},
                   {"translation", {1, 2, 3}},
                   {"rotation", {0, s, 0, c}},
                   {"scale", {2, 2, 2}}});
  b.push("cameras", {{"type", "perspective"},
                     {"perspective", {{"yfov", kPi / 4}, {"aspectRatio", 2.0}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 0}, {"translation", {0, 0, 10}}});
  b.doc["extensionsUsed"] = {"KHR_lights_punctual", "KHR_materials_ior"};
  b.doc["extensions"]["KHR_lights_punctual"]["lights"] = {
      {{"type", "point"}, {"color", {1, 0.5, 0.25}}, {"intensity", 683}}};
  b.push("nodes",
         {{"translation", {0, 5, 0}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  b.doc["scenes"] = {{{"nodes", {0, 1, 2}}}};
  b.doc["scene"] = 0;
  return b;
}

void expect_near(const Vec3& a, const Vec3& b, float tol = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

void check_sample(const Scene& scene) {
  ASSERT_EQ(scene.meshes.size(), 1u);
  const TriangleMesh& m = scene.meshes[0];
  ASSERT_EQ(m.positions.size(), 4u);
  // (1, 0, 0) scaled by 2, turned 90 degrees about +y to (0, 0, -2), moved by (1, 2, 3).
  expect_near(m.positions[1], Vec3(1, 2, 1));
  expect_near(m.positions[2], Vec3(1, 4, 1));
  // The normal +z turns to +x.
  ASSERT_EQ(m.normals.size(), 4u);
  expect_near(m.normals[0], Vec3(1, 0, 0));
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));

  ASSERT_EQ(scene.materials.size(), 1u);
  EXPECT_EQ(scene.materials[0].name, "paint");
  const auto& k = std::get<MetallicRoughnessMaterial>(scene.materials[0].kind);
  expect_near(k.base_color.value, Vec3(0.5f, 0.25f, 0.125f));
  EXPECT_EQ(k.metallic.value, 0.f);
  EXPECT_EQ(k.roughness.value, 0.5f);
  EXPECT_FLOAT_EQ(k.ior, 1.33f);
  EXPECT_FALSE(scene.materials[0].textured);
  EXPECT_TRUE(m.uvs.empty());  // an untextured material reads no coordinates

  expect_near(scene.camera.eye, Vec3(0, 0, 10));
  expect_near(scene.camera.look_at, Vec3(0, 0, 9));
  EXPECT_NEAR(scene.camera.fov_y_deg, 45.f, 1e-4f);
  EXPECT_EQ(scene.film.width, 1080u);  // 540 rows at the camera's aspect ratio 2
  EXPECT_EQ(scene.film.height, 540u);

  ASSERT_EQ(scene.point_lights.size(), 1u);
  expect_near(scene.point_lights[0].position, Vec3(0, 5, 0));
  // 683 cd is 1 W/sr at the luminous efficacy of 683 lm/W.
  expect_near(scene.point_lights[0].intensity, Vec3(1, 0.5f, 0.25f));
}

TEST(Gltf, TextFileWithBufferFile) {
  TempDir dir;
  const GltfBuilder b = sample_scene();
  dir.write("model.bin", b.bin);
  const auto file = dir.write("model.gltf", b.gltf("model.bin"));
  const Scene scene = load_scene(file);
  check_sample(scene);
  EXPECT_EQ(scene.referenced, (std::vector<std::filesystem::path>{"model.gltf", "model.bin"}));
}

TEST(Gltf, BinaryFileGivesTheSameScene) {
  TempDir dir;
  const auto file = dir.write("model.glb", sample_scene().glb());
  const Scene scene = load_scene(file);
  check_sample(scene);
  EXPECT_EQ(scene.referenced, (std::vector<std::filesystem::path>{"model.glb"}));
}

// `rayfarm render model.gltf` in the model's own folder: the file's path has no folder part, which
// must read as the working directory (with its buffer beside it), directly and through a JSON
// scene.
TEST(Gltf, FileNamedWithoutAFolderIsReadFromTheWorkingDirectory) {
  TempDir dir;
  const GltfBuilder b = sample_scene();
  dir.write("model.bin", b.bin);
  dir.write("model.gltf", b.gltf("model.bin"));
  dir.write("scene.json", R"({"gltf": {"file": "model.gltf"}})");
  const std::filesystem::path here = std::filesystem::current_path();
  std::filesystem::current_path(dir.path());
  Scene direct, wrapped;
  std::string error;
  try {
    direct = load_scene("model.gltf");
    wrapped = load_scene("scene.json");
  } catch (const std::exception& e) {
    error = e.what();
  }
  std::filesystem::current_path(here);
  ASSERT_EQ(error, "");
  check_sample(direct);
  check_sample(wrapped);
}

TEST(Gltf, JsonSceneAddsFilmAndOverridesMaterials) {
  TempDir dir;
  dir.write("m.glb", sample_scene().glb());
  const auto file = dir.write("scene.json", R"({
    "gltf": {"file": "m.glb"},
    "film": {"width": 64, "height": 32},
    "materials": {"paint": {"type": "diffuse", "albedo": [0.1, 0.2, 0.3]},
                  "extra": {"type": "diffuse"}},
    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "paint"}],
    "render": {"spp": 4}
  })");
  const Scene scene = load_scene(file);
  EXPECT_EQ(scene.film.width, 64u);
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_TRUE(std::holds_alternative<DiffuseMaterial>(scene.materials[0].kind));
  EXPECT_EQ(scene.meshes[0].materials[0], 0u);  // the glTF mesh now wears the override
  EXPECT_EQ(scene.spheres.at(0).material, 0u);
  expect_near(scene.camera.eye, Vec3(0, 0, 10));  // the glTF's camera
  EXPECT_EQ(scene.render.spp, 4u);
}

// The file's own material reads no texture, so on its own its mesh keeps no texture
// coordinates; replaced by a textured material from the JSON scene, the mesh keeps them (and
// its tangents), or the texture would be read at barycentrics.
TEST(Gltf, ReplacedMaterialsKeepTheMeshTextureCoordinates) {
  TempDir dir;
  GltfBuilder b = sample_scene();
  const int tangents = b.add_floats({1, 0, 0, 1, 0, 0, 0, -1, 1, 0, 0, 1, 1, 0, 0, 1}, "VEC4");
  b.doc["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = tangents;  // one zero tangent
  dir.write("m.glb", b.glb());
  EXPECT_TRUE(load_scene(dir.path() / "m.glb").meshes[0].uvs.empty());
  const Scene scene = load_scene(dir.write("scene.json", R"({
    "gltf": {"file": "m.glb"},
    "textures": {"c": {"type": "checkerboard", "color0": [0, 0, 0], "color1": [1, 1, 1]}},
    "materials": {"paint": {"type": "diffuse", "albedo": {"texture": "c"}}}
  })"));
  ASSERT_EQ(scene.meshes[0].uvs.size(), 4u);
  ASSERT_EQ(scene.meshes[0].tangents.size(), 4u);
  // Exporters write zero tangents where texture coordinates are degenerate: kept as zero (the
  // renderer derives the frame there), not an error.
  EXPECT_EQ(scene.meshes[0].tangents[1].x, 0.f);
  EXPECT_EQ(scene.meshes[0].tangents[1].w, -1.f);
  const Vec4& t0 = scene.meshes[0].tangents[0];  // +x, turned by the node to -z
  expect_near(Vec3(t0.x, t0.y, t0.z), Vec3(0, 0, -1));
}

TEST(Gltf, CameraChosenByName) {
  GltfBuilder b = sample_scene();
  b.doc["cameras"].push_back(
      {{"type", "orthographic"},
       {"name", "top"},
       {"orthographic", {{"xmag", 4}, {"ymag", 2}, {"znear", 0}, {"zfar", 9}}}});
  b.push("nodes", {{"camera", 1},
                   {"translation", {0, 7, 0}},
                   {"rotation", {-std::sin(kPi / 4), 0, 0, std::cos(kPi / 4)}}});
  b.doc["scenes"][0]["nodes"].push_back(3);
  TempDir dir;
  const auto file = dir.write("m.glb", b.glb());
  GltfOptions options;
  options.camera = "top";
  const Scene scene = load_scene(file, {}, SceneImages::kKeep, options);
  EXPECT_EQ(scene.camera.projection, Camera::Projection::kOrthographic);
  EXPECT_FLOAT_EQ(scene.camera.view_height, 4.f);
  expect_near(scene.camera.eye, Vec3(0, 7, 0));
  expect_near(scene.camera.look_at, Vec3(0, 6, 0));  // turned to look down
  EXPECT_EQ(scene.film.width, 1080u);
  options.camera = "nowhere";
  EXPECT_THROW(load_scene(file, {}, SceneImages::kKeep, options), SceneError);
}

TEST(Gltf, TexturesWithSamplersAndTransforms) {
  GltfBuilder b;
  testing::PngSpec png;
  png.width = 2;
  png.height = 1;
  png.samples = {255, 0, 0, 0, 0, 255};
  const testing::Bytes bytes = testing::encode_png(png);
  const int view = b.add_view(std::string(bytes.begin(), bytes.end()));
  b.push("images", {{"bufferView", view}, {"mimeType", "image/png"}});
  b.push("samplers", {{"magFilter", 9728}, {"wrapS", 33071}, {"wrapT", 33648}});
  b.push("textures", {{"source", 0}, {"sampler", 0}});
  const int material = b.push(
      "materials", {{"pbrMetallicRoughness",
                     {{"baseColorTexture",
                       {{"index", 0},
                        {"extensions",
                         {{"KHR_texture_transform",
                           {{"offset", {0.5, 0}}, {"rotation", 0.25}, {"scale", {2, 3}}}}}}}},
                      {"metallicRoughnessTexture", {{"index", 0}}}}}});
  b.push("nodes", {{"mesh", b.add_quad(material)}});
  TempDir dir;
  const Scene scene = load_scene(dir.write("t.glb", b.glb()));
  ASSERT_EQ(scene.textures.size(), 2u);  // sRGB colour, linear metal-roughness
  const TextureDesc& colour = scene.textures[0];
  EXPECT_EQ(colour.space, ColourSpace::srgb);
  EXPECT_EQ(colour.options.origin, UvOrigin::top_left);
  EXPECT_EQ(colour.options.filter, TextureFilter::nearest);
  EXPECT_EQ(colour.options.wrap_u, TextureWrap::clamp);
  EXPECT_EQ(colour.options.wrap_v, TextureWrap::mirror);
  // The extension's rotation is UvTransform's, unchanged (not the transposed GLSL listing):
  // UvTransform.FollowsKhrTextureTransform maps the extension's own worked example with it.
  EXPECT_FLOAT_EQ(colour.options.transform.rotation, 0.25f);
  EXPECT_FLOAT_EQ(colour.options.transform.scale[1], 3.f);
  ASSERT_TRUE(colour.image);
  EXPECT_EQ(colour.image->width, 2u);
  EXPECT_EQ(scene.textures[1].space, ColourSpace::linear);
  const auto& k = std::get<MetallicRoughnessMaterial>(scene.materials[0].kind);
  EXPECT_EQ(k.base_color.texture, 0);
  EXPECT_EQ(k.metallic.texture, 1);
  EXPECT_EQ(k.metallic.channel, TextureChannel::kB);
  EXPECT_EQ(k.roughness.channel, TextureChannel::kG);
  EXPECT_TRUE(scene.materials[0].textured);
  EXPECT_EQ(scene.meshes[0].uvs.size(), 4u);
  // Loaded to be checked only: the image is decoded, then dropped.
  const Scene checked = load_scene(dir.path() / "t.glb", {}, SceneImages::kCheckOnly);
  EXPECT_FALSE(checked.textures[0].image);
}

// One texture per distinct transform, told apart by the exact values: offsets 1e-7 apart are two
// textures, the same offset written twice is one.
TEST(Gltf, TexturesAreSharedOnlyUnderTheSameTransform) {
  GltfBuilder b;
  testing::PngSpec png;
  png.width = 1;
  png.height = 1;
  png.samples = {255, 0, 0};
  const testing::Bytes bytes = testing::encode_png(png);
  b.push("images", {{"bufferView", b.add_view(std::string(bytes.begin(), bytes.end()))},
                    {"mimeType", "image/png"}});
  b.push("textures", {{"source", 0}});
  auto shifted = [&](double offset) {
    return b.push("materials",
                  {{"pbrMetallicRoughness",
                    {{"baseColorTexture",
                      {{"index", 0},
                       {"extensions", {{"KHR_texture_transform", {{"offset", {offset, 0}}}}}}}}}}});
  };
  for (int material : {shifted(0.25), shifted(0.25 + 1e-7), shifted(0.25)})
    b.push("nodes", {{"mesh", b.add_quad(material)}});
  TempDir dir;
  const Scene scene = load_scene(dir.write("t.glb", b.glb()));
  ASSERT_EQ(scene.materials.size(), 3u);
  EXPECT_EQ(scene.textures.size(), 2u);
  auto texture_of = [&](size_t m) {
    return std::get<MetallicRoughnessMaterial>(scene.materials[m].kind).base_color.texture;
  };
  EXPECT_NE(texture_of(0), texture_of(1));
  EXPECT_EQ(texture_of(0), texture_of(2));
}

TEST(Gltf, NormalEmissiveAndAlphaTexturesAndTangents) {
  GltfBuilder b;
  testing::PngSpec png;
  png.width = 1;
  png.height = 1;
  png.color_type = PNG_COLOR_TYPE_RGB_ALPHA;
  png.samples = {128, 128, 255, 100};
  const testing::Bytes bytes = testing::encode_png(png);
  b.push("images", {{"bufferView", b.add_view(std::string(bytes.begin(), bytes.end()))},
                    {"mimeType", "image/png"}});
  b.push("textures", {{"source", 0}});
  const int cutout = b.push(
      "materials", {{"name", "leaf"},
                    {"alphaMode", "MASK"},
                    {"alphaCutoff", 0.25},
                    {"normalTexture", {{"index", 0}, {"scale", 0.5}}},
                    {"pbrMetallicRoughness",
                     {{"baseColorFactor", {1, 1, 1, 0.8}}, {"baseColorTexture", {{"index", 0}}}}}});
  const int glow =
      b.push("materials", {{"name", "sign"},
                           {"emissiveFactor", {1, 1, 1}},
                           {"emissiveTexture", {{"index", 0}}},
                           {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}},
                           {"alphaMode", "BLEND"}});
  const int leaf = b.add_quad(cutout);
  b.doc["meshes"][leaf]["primitives"][0]["attributes"]["TANGENT"] =
      b.add_floats({2, 0, 0, 1, 2, 0, 0, 1, 2, 0, 0, -1, 2, 0, 0, -1}, "VEC4");
  b.push("nodes", {{"mesh", leaf}});
  b.push("nodes", {{"mesh", b.add_quad(glow)}});
  TempDir dir;
  const Scene scene = load_scene(dir.write("s.glb", b.glb()));
  ASSERT_EQ(scene.materials.size(), 2u);
  const Material& m = scene.materials[0];
  ASSERT_TRUE(m.normal_map);
  EXPECT_EQ(scene.textures.at(m.normal_map->texture).space, ColourSpace::linear);
  EXPECT_FLOAT_EQ(m.normal_map->scale, 0.5f);
  EXPECT_FLOAT_EQ(m.alpha.value, 0.8f);
  EXPECT_EQ(m.alpha.channel, TextureChannel::kA);
  EXPECT_EQ(scene.textures.at(static_cast<size_t>(m.alpha.texture)).space, ColourSpace::srgb);
  EXPECT_FLOAT_EQ(m.alpha_cutoff, 0.25f);
  ASSERT_EQ(scene.meshes[0].tangents.size(), 4u);
  EXPECT_EQ(scene.meshes[0].tangents[0], Vec4(1, 0, 0, 1));
  EXPECT_EQ(scene.meshes[0].tangents[3].w, -1.f);
  EXPECT_EQ(scene.meshes[0].uvs.size(), 4u);
  // The emitter reads its texture; BLEND asks for partial coverage, which an emitter cannot have.
  const Material& e = scene.materials[1];
  EXPECT_TRUE(e.emission.is_textured());
  EXPECT_FALSE(e.has_alpha());
  EXPECT_EQ(scene.meshes[1].uvs.size(), 4u);
  std::string all;
  for (const std::string& w : scene.warnings) all += w + "\n";
  EXPECT_NE(all.find("cannot be cut out"), std::string::npos) << all;
}

/// The message of the SceneError that loading `b` as a .glb throws ("" when none).
TEST(Gltf, MalformedFilesNameThePlace) {
  {
    GltfBuilder b = sample_scene();
    b.doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 99;
    EXPECT_NE(glb_error(b).find("accessor 99 does not exist"), std::string::npos) << glb_error(b);
  }
  {
    GltfBuilder b = sample_scene();
    b.doc["accessors"][0]["count"] = 1000;  // positions past their view
    EXPECT_NE(glb_error(b).find("accessors[0]: 1000 elements"), std::string::npos) << glb_error(b);
  }
  {
    GltfBuilder b = sample_scene();
    b.doc["bufferViews"][3]["byteOffset"] = 1u << 20;
    EXPECT_NE(glb_error(b).find("bufferViews[3]"), std::string::npos) << glb_error(b);
  }
  {
    GltfBuilder b = sample_scene();
    const std::string index(4, '\x09');  // 0x09090909, past the 4 vertices
    b.doc["meshes"][0]["primitives"][0]["indices"] = b.add_indices({0, 1, 0x09090909u});
    EXPECT_NE(glb_error(b).find("index 2 is 151587081, past the 4 vertices"), std::string::npos)
        << glb_error(b);
  }
  {
    GltfBuilder b = sample_scene();
    b.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
    EXPECT_NE(glb_error(b).find("requires extension KHR_draco_mesh_compression"), std::string::npos)
        << glb_error(b);
  }
  {
    GltfBuilder b = sample_scene();
    b.doc["nodes"][0]["children"] = {0};  // a cycle
    EXPECT_NE(glb_error(b).find("nodes[0]: is reached twice"), std::string::npos) << glb_error(b);
  }
  {
    GltfBuilder b = sample_scene();
    b.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 5}};
    EXPECT_NE(glb_error(b).find("textures[5] does not exist"), std::string::npos) << glb_error(b);
  }
  {
    GltfBuilder b = sample_scene();
    b.push("images",
           {{"bufferView", b.add_view("not an image at all")}, {"mimeType", "image/png"}});
    b.push("textures", {{"source", 0}});
    b.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
    EXPECT_NE(glb_error(b).find("images[0]"), std::string::npos) << glb_error(b);
  }
  {
    GltfBuilder b = sample_scene();
    std::string glb = b.glb();
    glb.resize(glb.size() - 8);  // the binary chunk cut short
    TempDir dir;
    EXPECT_THROW(load_scene(dir.write("cut.glb", glb)), SceneError);
    EXPECT_THROW(load_scene(dir.write("junk.glb", "not a glb file at all, really")), SceneError);
  }
}

// What a few bytes of a hostile file could make the reader allocate is refused first: an
// accessor without a buffer view (all zeros, whatever its count), a binary chunk whose header
// claims bytes past the end of the file, and JSON of millions of empty objects.
TEST(Gltf, HostileSizesAreRefusedBeforeAllocating) {
  {
    GltfBuilder b = sample_scene();
    b.doc["accessors"][1].erase("bufferView");  // the normals
    b.doc["accessors"][1]["count"] = uint64_t{1} << 31;
    EXPECT_NE(glb_error(b).find("accessors[1]: count 2147483648 exceeds the limit"),
              std::string::npos)
        << glb_error(b);
  }
  {
    // Within one accessor's limit, beyond the file's vertices: refused before it is read.
    GltfBuilder b = sample_scene();
    b.doc["accessors"][0].erase("bufferView");
    b.doc["accessors"][0]["count"] = (uint64_t{1} << 26) + 1;
    b.doc["meshes"][0]["primitives"][0].erase("indices");
    b.doc["meshes"][0]["primitives"][0]["attributes"].erase("NORMAL");
    b.doc["meshes"][0]["primitives"][0]["attributes"].erase("TEXCOORD_0");
    EXPECT_NE(glb_error(b).find("more than 2^26 vertices"), std::string::npos) << glb_error(b);
  }
  {
    std::string glb = sample_scene().glb();
    uint32_t json_length;
    std::memcpy(&json_length, glb.data() + 12, 4);
    const size_t bin = 20 + json_length;
    uint32_t bin_length;
    std::memcpy(&bin_length, glb.data() + bin, 4);
    bin_length += 8;  // the data would end 8 bytes past the file
    std::memcpy(glb.data() + bin, &bin_length, 4);
    TempDir dir;
    try {
      load_scene(dir.write("long.glb", glb));
      ADD_FAILURE() << "a binary chunk longer than the file loaded";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("the binary chunk's length"), std::string::npos)
          << e.what();
    }
  }
  {
    GltfBuilder b = sample_scene();
    std::string many = "[";
    for (uint64_t i = 0; i <= kMaxGltfJsonObjects; ++i) many += i == 0 ? "{}" : ",{}";
    many += "]";
    TempDir dir;
    dir.write("m.bin", b.bin);
    std::string text = b.gltf("m.bin");
    text.insert(text.size() - 1, ",\"extras\":" + many);
    try {
      load_scene(dir.write("m.gltf", text));
      ADD_FAILURE() << "millions of empty objects loaded";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("JSON objects"), std::string::npos) << e.what();
    }
  }
  {
    // A NUL in a file's name would have the system open the name's first part.
    TempDir dir;
    const GltfBuilder b = sample_scene();
    dir.write("model.bin", b.bin);
    Json doc = Json::parse(b.gltf("model.bin"));
    doc["buffers"][0]["uri"] = std::string("model.bin\0.x", 12);
    EXPECT_THROW(load_scene(dir.write("nul.gltf", doc.dump())), SceneError);
  }
}

TEST(Gltf, BufferShorterThanDeclaredAndMissingFiles) {
  TempDir dir;
  const GltfBuilder b = sample_scene();
  dir.write("short.bin", b.bin.substr(0, b.bin.size() / 2));
  EXPECT_THROW(load_scene(dir.write("a.gltf", b.gltf("short.bin"))), SceneError);
  EXPECT_THROW(load_scene(dir.write("b.gltf", b.gltf("missing.bin"))), SceneError);
  // A file outside the scene's folder is refused for that reason, whether it exists or not.
  dir.write("outside.bin", b.bin);
  for (const char* uri : {"../outside.bin", "../no-such.bin", "sub/../../outside.bin"}) {
    try {
      load_scene(dir.write("scene/c.gltf", b.gltf(uri)));
      ADD_FAILURE() << uri << " outside the folder loaded";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("outside the scene's folder"), std::string::npos)
          << e.what();
      EXPECT_EQ(std::string(e.what()).find("not found"), std::string::npos) << e.what();
    }
  }
  GltfBuilder with_image = sample_scene();
  with_image.push("images", {{"uri", "absent.png"}});
  with_image.push("textures", {{"source", 0}});
  with_image.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
  dir.write("d.bin", with_image.bin);
  try {
    load_scene(dir.write("d.gltf", with_image.gltf("d.bin")));
    ADD_FAILURE() << "a missing image loaded";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("absent.png"), std::string::npos) << e.what();
  }
}

TEST(Gltf, UnsupportedFeaturesAreNamedInWarnings) {
  GltfBuilder b = sample_scene();
  b.doc["extensionsUsed"].push_back("KHR_materials_clearcoat");
  b.doc["animations"] = {{{"channels", Json::array()}, {"samplers", Json::array()}}};
  TempDir dir;
  const Scene scene = load_scene(dir.write("w.glb", b.glb()));
  std::string all;
  for (const std::string& w : scene.warnings) all += w + "\n";
  EXPECT_NE(all.find("KHR_materials_clearcoat"), std::string::npos) << all;
  // A file rendered directly plays its animations (gltf_animation_test.cpp); a JSON scene
  // without frames that names it does not, and says so.
  EXPECT_EQ(all.find("animations"), std::string::npos) << all;
  const Scene named = load_scene(dir.write("s.json", R"({
    "gltf": {"file": "w.glb"}, "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "fov_y": 40},
    "film": {"width": 8, "height": 8}})"));
  all.clear();
  for (const std::string& w : named.warnings) all += w + "\n";
  EXPECT_NE(all.find("animations: the scene has no \"animation\" block"), std::string::npos) << all;
}

TEST(Gltf, BlendIsPartialCoverage) {
  GltfBuilder b = sample_scene();
  b.doc["materials"][0]["alphaMode"] = "BLEND";
  b.doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = {1, 1, 1, 0.3};
  TempDir dir;
  const Scene scene = load_scene(dir.write("b.glb", b.glb()));
  const Material& m = scene.materials.at(0);
  EXPECT_TRUE(m.alpha_blend);
  EXPECT_FLOAT_EQ(m.alpha.value, 0.3f);
  EXPECT_TRUE(m.has_alpha());  // 0.3 is a cut-out at 0.5 no more: 30% of the rays stop
  for (const std::string& w : scene.warnings) EXPECT_EQ(w.find("BLEND"), std::string::npos) << w;
}

/// sample_scene() with its material made transmitting (factor 1), with `volume` as its
/// KHR_materials_volume (none when null), which the file requires.
GltfBuilder glass_scene(const Json& volume, double roughness = 0.0) {
  GltfBuilder b = sample_scene();
  Json& m = b.doc["materials"][0];
  m["pbrMetallicRoughness"]["roughnessFactor"] = roughness;
  m["extensions"]["KHR_materials_transmission"] = {{"transmissionFactor", 1.0}};
  b.doc["extensionsUsed"] = {"KHR_lights_punctual", "KHR_materials_ior",
                             "KHR_materials_transmission"};
  if (!volume.is_null()) {
    m["extensions"]["KHR_materials_volume"] = volume;
    b.doc["extensionsUsed"].push_back("KHR_materials_volume");
    b.doc["extensionsRequired"] = {"KHR_materials_volume"};
  }
  return b;
}

std::string all_warnings(const Scene& scene) {
  std::string all;
  for (const std::string& w : scene.warnings) all += w + "\n";
  return all;
}

TEST(Gltf, TransmissionWithAVolumeIsSolidGlass) {
  TempDir dir;
  {  // smooth: a dielectric of the file's ior, tinted by the base colour at each crossing
    const Scene scene =
        load_scene(dir.write("a.glb", glass_scene({{"thicknessFactor", 0.1}}).glb()));
    EXPECT_TRUE(scene.warnings.empty()) << all_warnings(scene);
    ASSERT_EQ(scene.materials.size(), 1u);
    const auto& d = std::get<DielectricMaterial>(scene.materials[0].kind);
    EXPECT_FLOAT_EQ(d.ior, 1.33f);
    expect_near(d.tint.value, Vec3(0.5f, 0.25f, 0.125f));
    EXPECT_FALSE(scene.materials[0].textured);
  }
  {  // rough: GGX alpha is the square of the perceptual roughness
    const Scene scene =
        load_scene(dir.write("b.glb", glass_scene({{"thicknessFactor", 2.0}}, 0.4).glb()));
    EXPECT_TRUE(scene.warnings.empty()) << all_warnings(scene);
    const auto& d = std::get<RoughDielectricMaterial>(scene.materials.at(0).kind);
    EXPECT_FLOAT_EQ(d.alpha_u.value, 0.16f);
    EXPECT_FLOAT_EQ(d.alpha_v.value, 0.16f);
    EXPECT_FLOAT_EQ(d.ior, 1.33f);
  }
  {  // without KHR_materials_ior, glTF's default index 1.5
    GltfBuilder b = glass_scene({{"thicknessFactor", 1.0}});
    b.doc["materials"][0]["extensions"].erase("KHR_materials_ior");
    const Scene scene = load_scene(dir.write("c.glb", b.glb()));
    EXPECT_FLOAT_EQ(std::get<DielectricMaterial>(scene.materials.at(0).kind).ior, 1.5f);
  }
}

TEST(Gltf, ThinOrOpaqueVolumesStayMetallicRoughness) {
  TempDir dir;
  // Zero thickness (the extension's default) is the thin wall again.
  for (const Json& volume : {Json::object(), Json{{"thicknessFactor", 0.0}}}) {
    const Scene scene = load_scene(dir.write("t.glb", glass_scene(volume).glb()));
    EXPECT_TRUE(scene.warnings.empty()) << all_warnings(scene);
    const auto& k = std::get<MetallicRoughnessMaterial>(scene.materials.at(0).kind);
    EXPECT_EQ(k.transmission.value, 1.f);
  }
  // Without transmission nothing enters the volume.
  GltfBuilder b = glass_scene({{"thicknessFactor", 1.0}});
  b.doc["materials"][0]["extensions"].erase("KHR_materials_transmission");
  const Scene scene = load_scene(dir.write("o.glb", b.glb()));
  EXPECT_EQ(std::get<MetallicRoughnessMaterial>(scene.materials.at(0).kind).transmission.value,
            0.f);
  // Nor on a metal: metallicFactor defaults to 1, and the metal covers the transmission.
  GltfBuilder metal = glass_scene({{"thicknessFactor", 1.0}});
  metal.doc["materials"][0]["pbrMetallicRoughness"].erase("metallicFactor");
  const Scene metal_scene = load_scene(dir.write("m.glb", metal.glb()));
  EXPECT_TRUE(metal_scene.warnings.empty()) << all_warnings(metal_scene);
  EXPECT_EQ(std::get<MetallicRoughnessMaterial>(metal_scene.materials.at(0).kind).metallic.value,
            1.f);
}

TEST(Gltf, VolumeAttenuationAndMixesAreNamedInWarnings) {
  GltfBuilder b = glass_scene({{"thicknessFactor", 1.0},
                               {"attenuationColor", {0.5, 0.9, 1.0}},
                               {"attenuationDistance", 0.2}});
  // A second glass material with attenuation: the absorption warning is given once per file.
  Json second = b.doc["materials"][0];
  second["name"] = "green glass";
  b.push("materials", second);
  b.doc["nodes"].push_back({{"mesh", b.add_quad(1)}});
  b.doc["scenes"][0]["nodes"].push_back(3);
  TempDir dir;
  {
    const Scene scene = load_scene(dir.write("a.glb", b.glb()));
    ASSERT_EQ(scene.materials.size(), 2u);
    for (const Material& m : scene.materials)
      EXPECT_TRUE(std::holds_alternative<DielectricMaterial>(m.kind)) << m.name;
    ASSERT_EQ(scene.warnings.size(), 1u) << all_warnings(scene);
    EXPECT_NE(scene.warnings[0].find("materials[0]/extensions/KHR_materials_volume"),
              std::string::npos)
        << scene.warnings[0];
    EXPECT_NE(scene.warnings[0].find("attenuation"), std::string::npos) << scene.warnings[0];
  }
  {  // a white attenuation colour, or an infinite distance, attenuates nothing: no warning
    GltfBuilder white = b;
    for (Json& m : white.doc["materials"])
      m["extensions"]["KHR_materials_volume"]["attenuationColor"] = {1.0, 1.0, 1.0};
    EXPECT_TRUE(load_scene(dir.write("w.glb", white.glb())).warnings.empty());
    GltfBuilder far = b;
    for (Json& m : far.doc["materials"])
      m["extensions"]["KHR_materials_volume"].erase("attenuationDistance");
    EXPECT_TRUE(load_scene(dir.write("f.glb", far.glb())).warnings.empty());
  }
  {  // half transmission and half metal cannot be one solid dielectric: said
    GltfBuilder mixed = glass_scene({{"thicknessFactor", 1.0}});
    mixed.doc["materials"][0]["extensions"]["KHR_materials_transmission"]["transmissionFactor"] =
        0.5;
    const Scene scene = load_scene(dir.write("m.glb", mixed.glb()));
    EXPECT_TRUE(std::holds_alternative<DielectricMaterial>(scene.materials.at(0).kind));
    EXPECT_NE(all_warnings(scene).find("transmissionFactor below 1"), std::string::npos)
        << all_warnings(scene);
  }
}

TEST(Gltf, MalformedVolumesNameThePlace) {
  const std::string at = "materials[0]/extensions/KHR_materials_volume/";
  const std::vector<std::pair<Json, std::string>> cases{
      {{{"thicknessFactor", -1.0}}, at + "thicknessFactor"},
      {{{"thicknessFactor", "thick"}}, at + "thicknessFactor"},
      {{{"thicknessFactor", 1.0}, {"attenuationDistance", 0.0}}, at + "attenuationDistance"},
      {{{"thicknessFactor", 1.0}, {"attenuationDistance", -2.0}}, at + "attenuationDistance"},
      {{{"thicknessFactor", 1.0}, {"attenuationColor", {1.0, 0.5}}}, at + "attenuationColor"},
      {{{"thicknessFactor", 1.0}, {"attenuationColor", {1.0, 0.5, 1.5}}}, at + "attenuationColor"},
  };
  for (const auto& [volume, where] : cases) {
    const std::string error = glb_error(glass_scene(volume));
    EXPECT_NE(error.find("bad.glb: " + where), std::string::npos) << volume << ": " << error;
  }
}

// A mesh placed by several nodes is stored once, as a group in its own space, with one instance
// per node whose matrix is the node's world transform (a parent's included, a mirror kept); a
// mesh placed by one node stays a world mesh.
TEST(Gltf, AMeshUsedByThreeNodesIsOneGroupAndThreeInstances) {
  GltfBuilder b;
  const int shared = b.add_quad(-1);
  const int single = b.add_quad(-1);
  const double s = std::sin(kPi / 4), c = std::cos(kPi / 4);
  b.push("nodes", {{"mesh", shared}, {"translation", {1, 2, 3}}, {"scale", {2, 2, 2}}});
  b.push("nodes", {{"translation", {10, 0, 0}}, {"children", {2}}});
  b.push("nodes", {{"mesh", shared}, {"rotation", {0, 0, s, c}}});  // 90 degrees about +z
  b.push("nodes", {{"mesh", shared}, {"translation", {0, 0, 5}}, {"scale", {-1, 1, 1}}});
  b.push("nodes", {{"mesh", single}, {"translation", {0, -3, 0}}});
  b.doc["scenes"] = {{{"nodes", {0, 1, 3, 4}}}};
  TempDir dir;
  const Scene scene = load_scene(dir.write("m.glb", b.glb()));
  ASSERT_EQ(scene.groups.size(), 1u);
  ASSERT_EQ(scene.groups[0].meshes.size(), 1u);
  EXPECT_EQ(scene.groups[0].meshes[0].positions,
            (std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}));
  ASSERT_EQ(scene.instances.size(), 3u);
  const std::array<double, 16> want[] = {
      {2, 0, 0, 1, 0, 2, 0, 2, 0, 0, 2, 3, 0, 0, 0, 1},
      {0, -1, 0, 10, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1},
      {-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 5, 0, 0, 0, 1},
  };
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(scene.instances[i].group, 0u);
    for (size_t k = 0; k < 16; ++k)
      EXPECT_NEAR(scene.instances[i].world_from_object[k], want[i][k], 1e-12)
          << "instance " << i << " element " << k;
  }
  ASSERT_EQ(scene.meshes.size(), 1u);  // the mesh used once, in the world
  EXPECT_EQ(scene.meshes[0].positions,
            (std::vector<Vec3>{{0, -3, 0}, {1, -3, 0}, {1, -2, 0}, {0, -2, 0}}));
  // Without a camera, the default view frames the instances too: their middle is above the world
  // mesh's, and the view looks at it.
  EXPECT_GT(scene.camera.look_at.x, 2.f);
  EXPECT_GT(scene.camera.look_at.z, 1.f);
}

// 2^19 + 1 nodes placing one mesh of 2^17 triangles: stored once, it is within the file's 2^26
// triangles, but placed it would be 2^36 + 2^17 triangles to traverse; refused, naming the node.
TEST(Gltf, InstancesMayPlaceAtMost2To36Triangles) {
  GltfBuilder b;
  const uint32_t strip = (1u << 17) + 2;  // a strip of n + 2 points has n triangles
  std::vector<float> points(3 * size_t(strip));
  for (uint32_t i = 0; i < strip; ++i) {
    points[3 * i] = float(i % 2);
    points[3 * i + 1] = float(i / 2) * 1e-3f;
  }
  const int pos = b.add_floats(points, "VEC3");
  b.push("meshes",
         {{"primitives", Json::array({{{"attributes", {{"POSITION", pos}}}, {"mode", 5}}})}});
  const size_t nodes = (size_t{1} << 19) + 1;
  b.doc["nodes"] = Json::array();
  Json roots = Json::array();
  for (size_t i = 0; i < nodes; ++i) {
    b.doc["nodes"].push_back({{"mesh", 0}});
    roots.push_back(i);
  }
  b.doc["scenes"] = {{{"nodes", roots}}};
  const std::string error = glb_error(b);
  EXPECT_NE(error.find("nodes[524288]: the nodes place more than 2^36 triangles in all"),
            std::string::npos)
      << error;
  // One node fewer is within the limit.
  b.doc["nodes"].erase(nodes - 1);
  roots.erase(nodes - 1);
  b.doc["scenes"] = {{{"nodes", roots}}};
  EXPECT_EQ(glb_error(b), "");
}

TEST(Gltf, NoCameraGivesADefaultView) {
  GltfBuilder b = sample_scene();
  b.doc["scenes"][0]["nodes"] = {0};
  TempDir dir;
  const Scene scene = load_scene(dir.write("n.glb", b.glb()));
  EXPECT_GT(scene.camera.eye.z, scene.camera.look_at.z);
  EXPECT_EQ(scene.film.width, 960u);
  EXPECT_FALSE(scene.warnings.empty());
}

}  // namespace
}  // namespace rayfarm
