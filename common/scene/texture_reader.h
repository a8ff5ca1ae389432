#pragma once
// The "textures" section of the JSON format and the parameters that may read a texture
// (docs/scene-format.md, "Textures").
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/limits.h"
#include "common/scene/json_reader.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// What happens to the images a scene's textures name: every one is decoded (a broken image is
/// a SceneError); kept in the Scene for rendering, or dropped once checked (the master, which
/// only needs to know that they are sound); or not read at all (kSkip: the extra poses of a
/// scene within an open shutter, whose images the scene's own pose has already read).
enum class SceneImages { kKeep, kCheckOnly, kSkip };

/// Decodes the image `file` (relative to `folder`) that node n names; a file that cannot be read
/// or decoded fails at n, naming the file. Null when `images` only asks for the check.
/// `sample_bytes`, when given, receives the size of the decoded samples.
std::shared_ptr<const DecodedImage> decode_scene_image(const scene_json::Node& n,
                                                       const std::filesystem::path& folder,
                                                       const std::filesystem::path& file,
                                                       SceneImages images, const char* what,
                                                       uint64_t* sample_bytes = nullptr);

/// Reads the textures of the scene in `folder` and their images; each file is decoded once,
/// however many textures name it. `referenced` gets the image files.
class TextureReader {
 public:
  /// `sample_budget`: the most bytes of samples that the distinct images may hold together.
  TextureReader(std::filesystem::path folder, SceneImages images,
                uint64_t sample_budget = kMaxSceneTextureBytes)
      : folder_(std::move(folder)), images_(images), sample_budget_(sample_budget) {}

  /// The "textures" object: name -> texture.
  void read(const scene_json::Node& n, std::vector<TextureDesc>& out,
            std::vector<std::filesystem::path>& referenced);

  /// A reflectance: an RGB in [0, 1], or {"texture": NAME, "scale": RGB or number in [0, 1]}
  /// (the texture's value, clamped to [0, 1], times the scale).
  TexturedRgb reflectance(const scene_json::Node& n) const;
  /// A radiance: an RGB >= 0, or {"texture": NAME, "scale": RGB or number >= 0} (the texture's
  /// value, unclamped, times the scale).
  TexturedRgb radiance(const scene_json::Node& n) const;
  /// The index of the texture that n names.
  int32_t texture_index(const scene_json::Node& n) const { return texture_ref(n); }
  /// A number in [lo, hi], or {"texture": NAME, "channel": "r"|"g"|"b"|"a"|"mean", "scale": x}.
  TexturedFloat number(const scene_json::Node& n, float lo, float hi) const;
  /// How many textured parameters have been read: a material whose reading raised it is
  /// textured.
  uint64_t textured_reads() const { return textured_reads_; }

 private:
  int32_t texture_ref(const scene_json::Node& n) const;
  /// {"texture": NAME, "scale": ...}: the texture, its scale (1) left to the caller.
  TexturedRgb colour_texture(const scene_json::Node& n) const;
  std::shared_ptr<const DecodedImage> image(const scene_json::Node& n,
                                            const std::filesystem::path& file);

  std::filesystem::path folder_;
  SceneImages images_;
  uint64_t sample_budget_;
  std::map<std::string, int32_t> index_;
  std::map<std::filesystem::path, std::shared_ptr<const DecodedImage>> decoded_;
  mutable uint64_t textured_reads_ = 0;
  uint64_t decoded_bytes_ = 0;  ///< samples of every distinct image decoded so far
};

}  // namespace rayfarm
