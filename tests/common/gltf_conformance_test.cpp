// What real glTF files use beyond the basics (docs/gltf.md): sparse and quantized accessors,
// COLOR_0 vertex colours, cameras chosen by index, compressed files named by their extension, a
// default view for a file without a camera, and a warning for a scene without light.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "common/bundle/bundle.h"
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

/// `values` as little-endian integers of `bytes` bytes each, in a new buffer view; its index.
template <class T>
int add_ints(GltfBuilder& b, const std::vector<T>& values) {
  std::string bytes(values.size() * sizeof(T), '\0');
  std::memcpy(bytes.data(), values.data(), bytes.size());
  return b.add_view(bytes);
}

/// A lit quad (a point light above it) with a camera: the smallest file that renders something.
GltfBuilder lit_quad() {
  GltfBuilder b;
  const int paint = b.push("materials", {{"pbrMetallicRoughness", {{"metallicFactor", 0.0}}}});
  b.push("nodes", {{"mesh", b.add_quad(paint)}});
  b.push("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 0}, {"translation", {0.5, 0.5, 3}}});
  b.doc["extensionsUsed"] = {"KHR_lights_punctual"};
  b.doc["extensions"]["KHR_lights_punctual"]["lights"] = {
      {{"type", "point"}, {"color", {1, 1, 1}}, {"intensity", 100}}};
  b.push("nodes",
         {{"translation", {0.5, 0.5, 2}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  return b;
}

bool has_warning(const Scene& scene, const std::string& part) {
  return std::any_of(scene.warnings.begin(), scene.warnings.end(),
                     [&](const std::string& w) { return w.find(part) != std::string::npos; });
}

TEST(GltfConformance, SparseAccessorsSubstituteTheirElements) {
  GltfBuilder b = lit_quad();
  // POSITION becomes sparse: vertex 2 moves from (1, 1, 0) to (2, 3, 0).
  Json& position = b.doc["accessors"][0];
  position["sparse"] = {{"count", 1},
                        {"indices", {{"bufferView", add_ints<uint16_t>(b, {2})},
                                     {"componentType", 5123}}},
                        {"values", {{"bufferView", add_ints<float>(b, {2.f, 3.f, 0.f})}}}};
  TempDir dir;
  const Scene scene = load_scene(dir.write("sparse.glb", b.glb()));
  ASSERT_EQ(scene.meshes.size(), 1u);
  const TriangleMesh& m = scene.meshes[0];
  EXPECT_EQ(m.positions[1], Vec3(1, 0, 0));
  EXPECT_EQ(m.positions[2], Vec3(2, 3, 0));

  // Without a buffer view the base is zeros: a sparse accessor alone gives every element.
  GltfBuilder z = lit_quad();
  z.doc["accessors"][0].erase("bufferView");
  z.doc["accessors"][0]["sparse"] = {
      {"count", 4},
      {"indices", {{"bufferView", add_ints<uint8_t>(z, {0, 1, 2, 3})}, {"componentType", 5121}}},
      {"values", {{"bufferView", add_ints<float>(z, {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0})}}}};
  const Scene zs = load_scene(dir.write("zeros.glb", z.glb()));
  EXPECT_EQ(zs.meshes.at(0).positions[3], Vec3(0, 1, 0));
}

TEST(GltfConformance, MalformedSparseAccessorsNameThePlace) {
  auto with_sparse = [](std::vector<uint32_t> indices, int count, size_t values) {
    GltfBuilder b = lit_quad();
    b.doc["accessors"][0]["sparse"] = {
        {"count", count},
        {"indices", {{"bufferView", add_ints<uint32_t>(b, indices)}, {"componentType", 5125}}},
        {"values", {{"bufferView", add_ints<float>(b, std::vector<float>(values, 0.f))}}}};
    return glb_error(b);
  };
  EXPECT_NE(with_sparse({3, 1}, 2, 6).find("accessors[0]/sparse/indices: index 1 is 1: indices "
                                           "must increase"),
            std::string::npos);
  EXPECT_NE(with_sparse({4}, 1, 3).find("index 0 is 4"), std::string::npos);
  EXPECT_NE(with_sparse({0}, 9, 27).find("accessors[0]/sparse/count"), std::string::npos);
  EXPECT_NE(with_sparse({0, 1}, 2, 3).find("accessors[0]/sparse/values: 2 elements of 12 bytes "
                                           "do not fit"),
            std::string::npos);
}

TEST(GltfConformance, QuantizedAttributesAreRead) {
  GltfBuilder b = lit_quad();
  b.doc["extensionsUsed"].push_back("KHR_mesh_quantization");
  b.doc["extensionsRequired"] = {"KHR_mesh_quantization"};
  // Positions as plain shorts (a node scale brings them back), texture coordinates as normalized
  // unsigned shorts: the extension's usual layout. Shorts are padded to 4-byte elements.
  const int positions = add_ints<int16_t>(b, {0, 0, 0, 0, 4, 0, 0, 0, 4, 4, 0, 0, 0, 4, 0, 0});
  b.doc["bufferViews"][positions]["byteStride"] = 8;
  b.doc["accessors"][0] = {
      {"bufferView", positions}, {"componentType", 5122}, {"count", 4}, {"type", "VEC3"}};
  b.doc["nodes"][0]["scale"] = {0.25, 0.25, 0.25};
  TempDir dir;
  const Scene scene = load_scene(dir.write("quantized.glb", b.glb()));
  const TriangleMesh& m = scene.meshes.at(0);
  EXPECT_EQ(m.positions[2], Vec3(1, 1, 0));
  EXPECT_FALSE(has_warning(scene, "KHR_mesh_quantization"));
}

TEST(GltfConformance, ACompressedFileNamesItsExtension) {
  for (const char* extension : {"KHR_draco_mesh_compression", "EXT_meshopt_compression"}) {
    GltfBuilder b = lit_quad();
    // As a compressor writes it: the attributes' accessors have no buffer view, the compressed
    // data is in the primitive's extension.
    for (Json& a : b.doc["accessors"]) a.erase("bufferView");
    b.doc["meshes"][0]["primitives"][0]["extensions"][extension] = {
        {"bufferView", 0}, {"attributes", {{"POSITION", 0}}}};
    b.doc["extensionsUsed"].push_back(extension);
    b.doc["extensionsRequired"] = {extension};
    const std::string error = glb_error(b);
    EXPECT_NE(error.find(std::string("extensionsRequired: the file requires extension ") +
                         extension + ", which rayfarm does not support"),
              std::string::npos)
        << error;
  }
}

TEST(GltfConformance, VertexColoursAreReadAsLinearRgb) {
  GltfBuilder b = lit_quad();
  // Normalized unsigned bytes, RGBA: 255 is 1.
  const int view = add_ints<uint8_t>(b, {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 51, 51,
                                         51, 255});
  const int colours = b.push("accessors", {{"bufferView", view},
                                           {"componentType", 5121},
                                           {"normalized", true},
                                           {"count", 4},
                                           {"type", "VEC4"}});
  b.doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = colours;
  TempDir dir;
  const Scene scene = load_scene(dir.write("colours.glb", b.glb()));
  const TriangleMesh& m = scene.meshes.at(0);
  ASSERT_EQ(m.colours.size(), 4u);
  EXPECT_EQ(m.colours[0], Vec3(1, 0, 0));
  EXPECT_EQ(m.colours[2], Vec3(0, 0, 1));
  EXPECT_FLOAT_EQ(m.colours[3].x, 0.2f);
  EXPECT_TRUE(scene.materials.at(m.materials[0]).vertex_colours);
  EXPECT_FALSE(has_warning(scene, "COLOR_0"));

  // A count that disagrees with POSITION, or a scalar accessor, names the place.
  b.doc["accessors"][colours]["count"] = 3;
  EXPECT_NE(glb_error(b).find("COLOR_0: 3 elements, but POSITION has 4"), std::string::npos);
  b.doc["accessors"][colours]["count"] = 4;
  b.doc["accessors"][colours]["type"] = "SCALAR";
  EXPECT_NE(glb_error(b).find("COLOR_0: must be a VEC3 or VEC4 accessor"), std::string::npos);
}

TEST(GltfConformance, ACameraIsChosenByIndexWhenNoNameMatches) {
  GltfBuilder b = lit_quad();
  b.push("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.5}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 1}, {"translation", {0.5, 0.5, 7}}});
  TempDir dir;
  const auto file = dir.write("two.glb", b.glb());
  GltfOptions options;
  options.camera = "1";
  const Scene second = load_scene(file, {}, SceneImages::kKeep, options);
  EXPECT_EQ(second.camera.eye, Vec3(0.5f, 0.5f, 7.f));
  options.camera = "0";
  EXPECT_EQ(load_scene(file, {}, SceneImages::kKeep, options).camera.eye, Vec3(0.5f, 0.5f, 3.f));
  options.camera = "2";
  try {
    load_scene(file, {}, SceneImages::kKeep, options);
    ADD_FAILURE() << "camera 2 of 2 was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("no camera named \"2\" placed by the scene's nodes (a "
                                         "camera's name, its node's name, or its index in "
                                         "cameras: the file has 2, numbered from 0)"),
              std::string::npos)
        << e.what();
  }
  // A camera named "0" is that camera, not the first of the file.
  b.doc["cameras"][1]["name"] = "0";
  options.camera = "0";
  EXPECT_EQ(load_scene(dir.write("named.glb", b.glb()), {}, SceneImages::kKeep, options).camera.eye,
            Vec3(0.5f, 0.5f, 7.f));
}

// A JSON scene naming a glTF file without a camera gets the view a direct render of the file
// gets, from an angle (a flat model is never seen edge-on), with a warning.
TEST(GltfConformance, AJsonSceneWithoutACameraGetsTheDefaultView) {
  GltfBuilder b = lit_quad();
  b.doc["nodes"].erase(1);  // the camera node
  b.doc.erase("cameras");
  b.doc["nodes"][1]["translation"] = {0.5, 0.5, 2};
  TempDir dir;
  const auto glb = dir.write("nocam.glb", b.glb());
  const Scene direct = load_scene(glb);
  const auto json = dir.write("scene.json", R"({"gltf": {"file": "nocam.glb"}})");
  const Scene via_json = load_scene(json);
  EXPECT_EQ(via_json.camera.eye, direct.camera.eye);
  EXPECT_EQ(via_json.camera.look_at, Vec3(0.5f, 0.5f, 0.f));  // the quad's middle
  EXPECT_TRUE(via_json.default_camera);
  EXPECT_TRUE(has_warning(via_json, "a default one frames the meshes"));
  // From the front, to the right and above: the quad (in z = 0) is seen at an angle.
  const Vec3 d = direct.camera.eye - direct.camera.look_at;
  EXPECT_GT(d.x, 0.f);
  EXPECT_GT(d.y, 0.f);
  EXPECT_GT(d.z, d.x);
  EXPECT_GT(d.z, d.y);
}

TEST(GltfConformance, AFileWithoutLightIsWarnedAbout) {
  GltfBuilder b = lit_quad();
  TempDir dir;
  EXPECT_FALSE(has_warning(load_scene(dir.write("lit.glb", b.glb())), "has no light"));
  b.doc["nodes"].erase(2);  // the light's node
  const Scene dark = load_scene(dir.write("dark.glb", b.glb()));
  EXPECT_TRUE(has_warning(dark, "dark.glb: the scene has no light")) << dark.warnings.size();
  // An emissive material lights it.
  b.doc["materials"][0]["emissiveFactor"] = {1, 1, 1};
  EXPECT_FALSE(has_warning(load_scene(dir.write("glow.glb", b.glb())), "has no light"));
  // So does an environment added by a JSON scene.
  b.doc["materials"][0].erase("emissiveFactor");
  dir.write("dark2.glb", b.glb());
  const auto json = dir.write(
      "sky.json", R"({"gltf": {"file": "dark2.glb"}, "lights": [{"type": "constant", "radiance": [1, 1, 1]}]})");
  EXPECT_FALSE(has_warning(load_scene(json), "has no light"));
}

// --environment (GltfOptions::environment) lights a file that has no light: a uniform sky, or an
// image in the file's folder that the farm's bundle carries with the file.
TEST(GltfConformance, AnEnvironmentLightsAFileAndTravelsWithIt) {
  GltfBuilder b = lit_quad();
  b.doc["nodes"].erase(2);  // no light of its own
  TempDir dir;
  const auto glb = dir.write("model/dark.glb", b.glb());
  GltfOptions options;
  options.environment = "uniform";
  const Scene uniform = load_scene(glb, {}, SceneImages::kKeep, options);
  ASSERT_TRUE(uniform.environment.has_value());
  EXPECT_TRUE(uniform.environment->file.empty());
  EXPECT_EQ(uniform.environment->scale, Vec3(1.f));
  EXPECT_FALSE(has_warning(uniform, "has no light"));

  const testing::Bytes exr =
      testing::encode_exr(std::vector<float>(8 * 4 * 3, 0.5f), 8, 4, {"R", "G", "B"}, false);
  dir.write("model/sky/studio.exr", std::string(exr.begin(), exr.end()));
  options.environment = "sky/studio.exr";
  const Scene mapped = load_scene(glb, {}, SceneImages::kKeep, options);
  ASSERT_TRUE(mapped.environment.has_value());
  EXPECT_EQ(mapped.environment->file, "sky/studio.exr");
  ASSERT_TRUE(mapped.environment->image);
  EXPECT_EQ(mapped.environment->image->width, 8u);

  // Packed for the farm: the image travels, and the bundle's scene says the same.
  const PackedScene packed = pack_gltf_scene(glb, "", "sky/studio.exr");
  std::vector<std::string> paths;
  for (const auto& f : packed.bundle.files) paths.push_back(f.path);
  EXPECT_EQ(paths,
            (std::vector<std::string>{"dark.glb", "dark.glb.camera.json", "sky/studio.exr"}));
  const auto unpacked = unpack_bundle(packed.bundle, dir.path() / "cache", packed.hash);
  const Scene farm = load_scene(unpacked / packed.scene_path);
  ASSERT_TRUE(farm.environment.has_value());
  EXPECT_EQ(farm.environment->file, "sky/studio.exr");
  EXPECT_EQ(farm.camera.eye, mapped.camera.eye);

  // A missing image is the scene's error, naming it.
  options.environment = "sky/none.exr";
  try {
    load_scene(glb, {}, SceneImages::kKeep, options);
    ADD_FAILURE() << "a missing environment image was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("none.exr"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rayfarm
