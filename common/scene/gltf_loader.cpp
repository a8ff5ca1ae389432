// glTF 2.0 files: read by tinygltf through our file and image callbacks (every file it opens
// stays inside the scene's folder and under the size limits; images are decoded by rayfarm's own
// decoders), then turned into the scene's meshes, materials, lights and camera (gltf_nodes.cpp).
#include "common/scene/gltf_loader.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <set>
#include <string_view>

#include <nlohmann/json.hpp>

#include "common/limits.h"
#include "common/scene/gltf_accessors.h"
#include "common/scene/gltf_animation.h"
#include "common/scene/gltf_materials.h"
#include "common/scene/gltf_nodes.h"
#include "common/util/read_file.h"
#include "common/util/text.h"

namespace rayfarm {
namespace fs = std::filesystem;

namespace {

/// What the file callbacks need: the scene's folder, and where the files read are recorded.
struct FileAccess {
  fs::path root;               ///< the scene's folder, absolute and normal
  std::vector<fs::path> read;  ///< files read, relative to root
  uint64_t bytes = 0;          ///< read so far, against kMaxGltfBytes
};

/// Inside the scene's folder: the path relative to it, or empty.
fs::path inside(const FileAccess& access, const std::string& path) {
  // A NUL would end the name that the system opens before the one checked here.
  if (path.find('\0') != std::string::npos) return {};
  const fs::path rel = fs::absolute(path).lexically_normal().lexically_relative(access.root);
  if (rel.empty() || rel.is_absolute() || *rel.begin() == "..") return {};
  return rel;
}

/// A path outside the scene's folder "exists" (whether it does is not looked up), so that the
/// reader goes on to read_whole() and the error names the real cause instead of "not found".
bool file_exists(const std::string& path, void* user) {
  if (inside(*static_cast<FileAccess*>(user), path).empty()) return true;
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

std::string expand_path(const std::string& path, void*) { return path; }  // no ~ nor $VARS

bool read_whole(std::vector<unsigned char>* out, std::string* err, const std::string& path,
                void* user) {
  auto& access = *static_cast<FileAccess*>(user);
  const fs::path rel = inside(access, path);
  if (rel.empty()) {
    if (err) *err += printable(path) + " lies outside the scene's folder\n";
    return false;
  }
  try {
    const std::string data = read_whole_file(path, kMaxGltfBytes - access.bytes);
    access.bytes += data.size();
    out->assign(data.begin(), data.end());
  } catch (const std::exception& e) {
    if (err) *err += printable(rel.generic_string()) + ": " + e.what() + "\n";
    return false;
  }
  if (std::find(access.read.begin(), access.read.end(), rel) == access.read.end())
    access.read.push_back(rel);
  return true;
}

bool write_whole(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "writing is not allowed\n";
  return false;
}

/// Keeps the bytes of an image from a file or a data URI for decoding later. An image in a
/// buffer view is left alone: tinygltf hands it over before checking the view against its
/// buffer, so it is read only from the view once gltf::buffer_view_bytes() has checked it.
bool keep_image(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                const unsigned char* bytes, int size, void* user) {
  if (image->bufferView >= 0 || size <= 0) return true;
  (*static_cast<gltf::ImageBytes*>(user))[index].assign(bytes, bytes + size);
  return true;
}

/// Fails when JSON text nests arrays and objects deeper than the scene format allows (the
/// parser tinygltf uses would recurse without bound while freeing it), or holds more objects or
/// values than kMaxGltfJsonObjects / kMaxGltfJsonValues: parsed, each costs tens to hundreds of
/// bytes, and a file of empty objects would ask for a hundred times its size.
void check_nesting(const char* text, size_t size, const std::string& display) {
  int depth = 0;
  bool in_string = false, escaped = false;
  uint64_t objects = 0, values = 0;
  for (size_t i = 0; i < size; ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonNesting)
        throw SceneError(display + ": JSON nested deeper than " + std::to_string(kMaxJsonNesting) +
                         " levels (byte " + std::to_string(i) + ")");
      if (c == '{' && ++objects > kMaxGltfJsonObjects)
        throw SceneError(display + ": more than " + std::to_string(kMaxGltfJsonObjects) +
                         " JSON objects (byte " + std::to_string(i) + ")");
      ++values;
    } else if (c == ']' || c == '}') {
      --depth;
    } else if (c == ',') {
      ++values;  // one more element or member
    }
    if (values > kMaxGltfJsonValues)
      throw SceneError(display + ": more than " + std::to_string(kMaxGltfJsonValues) +
                       " JSON values (byte " + std::to_string(i) + ")");
  }
}

uint32_t le32(const std::string& s, size_t at) {
  uint32_t v;
  std::memcpy(&v, s.data() + at, 4);
  return v;
}

/// The JSON chunk of a GLB container, checked against the file's length.
std::pair<size_t, size_t> glb_json_chunk(const std::string& data, const std::string& display) {
  if (data.size() < 20 || data.compare(0, 4, "glTF") != 0)
    throw SceneError(display + ": not a binary glTF file (no \"glTF\" magic at byte 0)");
  if (le32(data, 4) != 2)
    throw SceneError(display + ": binary glTF version " + std::to_string(le32(data, 4)) +
                     "; rayfarm reads version 2");
  if (le32(data, 8) != data.size())
    throw SceneError(display + ": the header states " + std::to_string(le32(data, 8)) +
                     " bytes, the file has " + std::to_string(data.size()));
  const size_t length = le32(data, 12);
  if (le32(data, 16) != 0x4E4F534Au)
    throw SceneError(display + ": byte 16: the first chunk is not JSON");
  if (length > data.size() - 20)
    throw SceneError(display + ": byte 12: the JSON chunk's length " + std::to_string(length) +
                     " runs past the end of the file");
  // The binary chunk, when there is one: its 8-byte header and its data must lie in the file
  // (the reader checks the data's length without the header, and would read past the end).
  const size_t bin = 20 + length;
  if (bin < data.size()) {
    if (data.size() - bin < 8)
      throw SceneError(display + ": byte " + std::to_string(bin) +
                       ": a chunk header cut short by the end of the file");
    const size_t bin_length = le32(data, bin);
    if (bin_length > data.size() - bin - 8)
      throw SceneError(display + ": byte " + std::to_string(bin) + ": the binary chunk's length " +
                       std::to_string(bin_length) + " runs past the end of the file");
  }
  return {20, length};
}

const std::set<std::string>& supported_extensions() {
  static const std::set<std::string> names{
      "KHR_lights_punctual",        "KHR_mesh_quantization", "KHR_materials_ior",
      "KHR_materials_transmission", "KHR_materials_volume",  "KHR_materials_emissive_strength",
      "KHR_texture_transform"};
  return names;
}

/// The first extension in the JSON's extensionsRequired that rayfarm does not support, or "".
/// Read before tinygltf parses the file: a compressed mesh (Draco, meshopt) has accessors without
/// buffer views that tinygltf refuses with its own words, before the extension could be named.
std::string first_unsupported_required(const char* text, size_t size) {
  // Most files require nothing: they are not parsed twice.
  if (std::string_view(text, size).find("extensionsRequired") == std::string_view::npos) return {};
  const nlohmann::json doc = nlohmann::json::parse(text, text + size, nullptr, false);
  if (!doc.is_object()) return {};  // not JSON: tinygltf says why
  const auto it = doc.find("extensionsRequired");
  if (it == doc.end() || !it->is_array()) return {};
  for (const nlohmann::json& name : *it) {
    if (name.is_string() && !supported_extensions().count(name.get<std::string>()))
      return name.get<std::string>();
  }
  return {};
}

void check_extensions(const gltf::Source& src) {
  for (const std::string& name : src.model->extensionsRequired) {
    if (!supported_extensions().count(name))
      src.fail("extensionsRequired", "the file requires extension " + printable(name) +
                                         ", which rayfarm does not support");
  }
  std::string ignored;
  for (const std::string& name : src.model->extensionsUsed) {
    if (!supported_extensions().count(name)) ignored += (ignored.empty() ? "" : ", ") + name;
  }
  if (!ignored.empty())
    src.warn("extensionsUsed",
             "extensions not supported, their data is ignored: " + printable(ignored));
  if (!src.model->skins.empty())
    src.warn("skins", "skins are not supported; skinned meshes are rendered in their bind pose");
}

}  // namespace

bool is_gltf_path(const fs::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".gltf" || ext == ".glb";
}

GltfResult load_gltf(const fs::path& folder, const fs::path& relative, const GltfOptions& options,
                     SceneImages images, Scene& scene) {
  const fs::path path = folder / relative;
  const std::string display = path.string();
  std::string data;
  try {
    data = read_whole_file(path, kMaxGltfBytes);
  } catch (const std::exception& e) {
    throw SceneError(display + ": " + e.what());
  }
  std::string ext = relative.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const bool binary = ext == ".glb";
  const auto [json_at, json_length] =
      binary ? glb_json_chunk(data, display) : std::pair<size_t, size_t>{0, data.size()};
  check_nesting(data.data() + json_at, json_length, display);
  if (const std::string name = first_unsupported_required(data.data() + json_at, json_length);
      !name.empty()) {
    throw SceneError(display + ": extensionsRequired: the file requires extension " +
                     printable(name) + ", which rayfarm does not support");
  }
  if (data.size() > UINT32_MAX) throw SceneError(display + ": larger than 4 GiB");

  FileAccess access;
  // A file named without a folder lies in the working directory (fs::absolute refuses "").
  access.root = (folder.empty() ? fs::current_path() : fs::absolute(folder)).lexically_normal();
  access.bytes = data.size();
  gltf::ImageBytes image_bytes;
  tinygltf::TinyGLTF reader;
  reader.SetFsCallbacks({&file_exists, &expand_path, &read_whole, &write_whole, &access});
  reader.SetImageLoader(&keep_image, &image_bytes);
  tinygltf::Model model;
  std::string err, warn;
  const std::string base = fs::absolute(path).parent_path().string();
  bool ok = false;
  try {
    ok = binary ? reader.LoadBinaryFromMemory(&model, &err, &warn,
                                              reinterpret_cast<const unsigned char*>(data.data()),
                                              static_cast<unsigned>(data.size()), base)
                : reader.LoadASCIIFromString(&model, &err, &warn, data.data(),
                                             static_cast<unsigned>(data.size()), base);
  } catch (const std::exception& e) {
    err += e.what();
    ok = false;
  }
  data.clear();
  data.shrink_to_fit();
  auto one_line = [](std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    std::replace(s.begin(), s.end(), '\n', ';');
    return printable(s);
  };
  if (!ok) throw SceneError(display + ": " + (err.empty() ? "not a glTF 2.0 file" : one_line(err)));
  if (!warn.empty()) scene.warnings.push_back(display + ": " + one_line(warn));

  gltf::Source src{display, &model, &scene.warnings};
  check_extensions(src);
  // The glTF file and every buffer and image file it read travel with the scene.
  auto add_referenced = [&](const fs::path& file) {
    if (std::find(scene.referenced.begin(), scene.referenced.end(), file) == scene.referenced.end())
      scene.referenced.push_back(file);
  };
  add_referenced(relative.lexically_normal());
  for (const fs::path& file : access.read) add_referenced(file);

  const double duration = gltf::animation_duration(src);
  if (options.time) {
    gltf::apply_animations(src, model, *options.time);
  } else if (!model.animations.empty()) {
    // A JSON scene without frames names an animated file: the file plays no part of it.
    src.warn("animations",
             "the scene has no \"animation\" block, so the file's animations are not played; "
             "the file is rendered as it stands (gltf.time poses it)");
  }
  gltf::Materials materials(src, scene, image_bytes, images, relative.lexically_normal());
  GltfResult result = gltf::read_nodes(src, materials, options, scene);
  result.duration = duration;
  return result;
}

}  // namespace rayfarm
