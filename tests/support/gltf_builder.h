#pragma once
// Builds small glTF 2.0 files for tests and fuzz seeds: a JSON document and one binary buffer,
// written as .gltf + .bin or as one .glb.
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace rayfarm::testing {

class GltfBuilder {
 public:
  using Json = nlohmann::json;
  Json doc = {{"asset", {{"version", "2.0"}}}};
  std::string bin;  ///< buffer 0

  /// A buffer view over `bytes` appended to buffer 0 (4-byte aligned); its index.
  int add_view(const std::string& bytes) {
    while (bin.size() % 4 != 0) bin.push_back('\0');
    Json view = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}};
    bin += bytes;
    return push("bufferViews", view);
  }
  /// A float accessor of `type` ("SCALAR", "VEC2", "VEC3", "VEC4"); its index.
  int add_floats(const std::vector<float>& values, const std::string& type) {
    const int components = type == "VEC2" ? 2 : type == "VEC3" ? 3 : type == "VEC4" ? 4 : 1;
    std::string bytes(values.size() * 4, '\0');
    std::memcpy(bytes.data(), values.data(), bytes.size());
    Json a = {{"bufferView", add_view(bytes)},
              {"componentType", 5126},
              {"count", values.size() / components},
              {"type", type}};
    return push("accessors", a);
  }
  /// An unsigned-int index accessor; its index.
  int add_indices(const std::vector<uint32_t>& values) {
    std::string bytes(values.size() * 4, '\0');
    std::memcpy(bytes.data(), values.data(), bytes.size());
    Json a = {{"bufferView", add_view(bytes)},
              {"componentType", 5125},
              {"count", values.size()},
              {"type", "SCALAR"}};
    return push("accessors", a);
  }
  /// Appends `value` to the top-level array `key`; its index.
  int push(const std::string& key, const Json& value) {
    if (!doc.contains(key)) doc[key] = Json::array();
    doc[key].push_back(value);
    return static_cast<int>(doc[key].size()) - 1;
  }
  /// A unit quad in the z = 0 plane facing +z, with normals and uvs, as mesh with `material`
  /// (-1: none); the mesh's index.
  int add_quad(int material) {
    const int pos = add_floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, "VEC3");
    const int nor = add_floats({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3");
    const int uv = add_floats({0, 1, 1, 1, 1, 0, 0, 0}, "VEC2");
    const int idx = add_indices({0, 1, 2, 0, 2, 3});
    Json prim = {{"attributes", {{"POSITION", pos}, {"NORMAL", nor}, {"TEXCOORD_0", uv}}},
                 {"indices", idx}};
    if (material >= 0) prim["material"] = material;
    return push("meshes", {{"primitives", Json::array({prim})}});
  }

  /// The document for a .gltf whose buffer is the file `bin_name`.
  std::string gltf(const std::string& bin_name) const {
    Json d = doc;
    d["buffers"] = Json::array({{{"uri", bin_name}, {"byteLength", bin.size()}}});
    return d.dump();
  }
  /// The whole .glb file.
  std::string glb() const {
    Json d = doc;
    d["buffers"] = Json::array({{{"byteLength", bin.size()}}});
    std::string json = d.dump();
    while (json.size() % 4 != 0) json.push_back(' ');
    std::string data = bin;
    while (data.size() % 4 != 0) data.push_back('\0');
    std::string out;
    auto u32 = [&out](uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
    out += "glTF";
    u32(2);
    u32(static_cast<uint32_t>(12 + 8 + json.size() + 8 + data.size()));
    u32(static_cast<uint32_t>(json.size()));
    u32(0x4E4F534Au);
    out += json;
    u32(static_cast<uint32_t>(data.size()));
    u32(0x004E4942u);
    out += data;
    return out;
  }
};

}  // namespace rayfarm::testing
