#pragma once
// glTF materials, textures and images as rayfarm's: every pbrMetallicRoughness texture with its
// sampler, texCoord and KHR_texture_transform, the normal and emissive textures, alpha modes and
// the KHR_materials_ior / _transmission / _volume / _emissive_strength extensions. Internal to the
// glTF loader; docs/gltf.md says what maps to what.
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <unordered_set>
#include <vector>

#include "common/scene/gltf_accessors.h"
#include "common/scene/scene.h"
#include "common/scene/texture_reader.h"

namespace rayfarm::gltf {

/// The bytes of each image that came from a file or a data URI (by image index); images in a
/// buffer view are read from their view once it has been checked.
using ImageBytes = std::map<int, std::vector<uint8_t>>;

class Materials {
 public:
  /// `image_prefix`: the glTF file relative to the scene folder, naming embedded images.
  Materials(const Source& src, Scene& scene, const ImageBytes& bytes, SceneImages images,
            std::filesystem::path gltf_file);

  /// The scene's material for glTF material `index` (-1: the specification's default material),
  /// added on first use.
  uint32_t material(int index);
  /// The TEXCOORD set that material `index`'s textures read (0 when it has none).
  int texcoord(int index);

 private:
  Material convert(int index);
  /// The solid dielectric that a transmitting material with KHR_materials_volume (thickness > 0)
  /// bounds, or nothing when `g` is thin-walled; `k` is its metallic-roughness reading.
  std::optional<MaterialKind> volume(const tinygltf::Material& g,
                                     const MetallicRoughnessMaterial& k, const std::string& where);
  /// The scene texture for glTF texture `info_index` as read in `space`; `texcoord` receives its
  /// TEXCOORD set; `where` names the texture info for messages.
  int32_t texture(int index, int uv_set, const tinygltf::ExtensionMap& extensions,
                  ColourSpace space, const std::string& where);
  std::shared_ptr<const DecodedImage> image(int index, const std::string& where);

  const Source& src_;
  Scene& scene_;
  const ImageBytes& bytes_;
  SceneImages images_;
  std::filesystem::path gltf_file_;
  std::map<int, uint32_t> materials_;  // glTF material -> scene material
  std::unordered_set<std::string> names_;  // of scene_.materials, filled at the first material
  std::map<int, int> texcoords_;       // glTF material -> its TEXCOORD set
  std::map<std::tuple<int, ColourSpace, std::string>, int32_t> textures_;
  std::map<int, std::shared_ptr<const DecodedImage>> decoded_;
  uint64_t decoded_bytes_ = 0;
  bool attenuation_warned_ = false;
};

}  // namespace rayfarm::gltf
