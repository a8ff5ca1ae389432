#include "common/scene/gltf_materials.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <span>

#include "common/image/decode_image.h"
#include "common/limits.h"

namespace rayfarm::gltf {
namespace fs = std::filesystem;

namespace {

std::string material_name(int index) { return "materials[" + std::to_string(index) + "]"; }

/// A number of an extension object, or `fallback` when absent; fails when not a number.
double ext_number(const Source& src, const tinygltf::Value& object, const std::string& key,
                  double fallback, const std::string& where) {
  if (!object.IsObject() || !object.Has(key)) return fallback;
  const tinygltf::Value& v = object.Get(key);
  if (!v.IsNumber()) src.fail(where + "/" + key, "expected a number");
  const double x = v.GetNumberAsDouble();
  if (!std::isfinite(x)) src.fail(where + "/" + key, "not a finite number");
  return x;
}

constexpr int kMaxTexcoordSet = 255;

/// The "texCoord" of an extension object: an integer in [0, 255], or `fallback` when absent.
int texcoord_set(const Source& src, const tinygltf::Value& object, int fallback,
                 const std::string& where) {
  const double x = ext_number(src, object, "texCoord", fallback, where);
  if (!(x >= 0.0 && x <= kMaxTexcoordSet) || x != std::floor(x))
    src.fail(where + "/texCoord", "must be an integer in [0, 255]");
  return static_cast<int>(x);
}

/// Reads a factor in [0, 1].
float unit_factor(const Source& src, double x, const std::string& where) {
  if (!(x >= 0.0 && x <= 1.0)) src.fail(where, "must lie in [0, 1], is " + std::to_string(x));
  return static_cast<float>(x);
}

TextureWrap wrap_mode(int gl) {
  switch (gl) {
    case TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE:
      return TextureWrap::clamp;
    case TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT:
      return TextureWrap::mirror;
    default:
      return TextureWrap::repeat;
  }
}

}  // namespace

Materials::Materials(const Source& src, Scene& scene, const ImageBytes& bytes, SceneImages images,
                     fs::path gltf_file)
    : src_(src), scene_(scene), bytes_(bytes), images_(images), gltf_file_(std::move(gltf_file)) {}

uint32_t Materials::material(int index) {
  if (auto it = materials_.find(index); it != materials_.end()) return it->second;
  Material m = convert(index);
  // Names stay unique, so that a JSON scene can override a glTF material by its name. A set,
  // not a search: a file may hold millions of materials.
  if (names_.empty())
    for (const Material& other : scene_.materials) names_.insert(other.name);
  if (names_.count(m.name)) m.name += " (" + material_name(index) + ")";
  names_.insert(m.name);
  const auto scene_index = static_cast<uint32_t>(scene_.materials.size());
  scene_.materials.push_back(std::move(m));
  materials_[index] = scene_index;
  return scene_index;
}

int Materials::texcoord(int index) {
  (void)material(index);
  const auto it = texcoords_.find(index);
  return it == texcoords_.end() ? 0 : it->second;
}

Material Materials::convert(int index) {
  Material m;
  MetallicRoughnessMaterial k;  // the defaults are the specification's default material
  if (index < 0) {
    m.name = "gltf:default";
    m.kind = k;
    return m;
  }
  const auto& all = src_.model->materials;
  if (static_cast<size_t>(index) >= all.size())
    src_.fail(material_name(index),
              "does not exist (the file has " + std::to_string(all.size()) + " materials)");
  const tinygltf::Material& g = all[static_cast<size_t>(index)];
  const std::string where = material_name(index);
  m.name = g.name.empty() ? "gltf:" + where : g.name;
  const tinygltf::PbrMetallicRoughness& pbr = g.pbrMetallicRoughness;

  int texcoord = -1;
  auto note_texcoord = [&](int set, const std::string& at) {
    if (texcoord < 0) {
      texcoord = set;
    } else if (set != texcoord) {
      src_.warn(at, "reads TEXCOORD_" + std::to_string(set) + " where the material's other " +
                        "textures read TEXCOORD_" + std::to_string(texcoord) +
                        "; a mesh has one set of texture coordinates, so it reads TEXCOORD_" +
                        std::to_string(texcoord));
    }
  };
  auto textured = [&](const auto& info, ColourSpace space, const std::string& at) {
    int set = info.texCoord;
    const auto ext = info.extensions.find("KHR_texture_transform");
    if (ext != info.extensions.end() && ext->second.Has("texCoord"))
      set = texcoord_set(src_, ext->second, set, at + "/extensions/KHR_texture_transform");
    if (set < 0 || set > kMaxTexcoordSet) src_.fail(at + "/texCoord", "must lie in [0, 255]");
    note_texcoord(set, at);
    return texture(info.index, set, info.extensions, space, at);
  };

  if (pbr.baseColorFactor.size() != 4)
    src_.fail(where + "/pbrMetallicRoughness/baseColorFactor", "expected 4 numbers");
  float base[3];
  for (size_t c = 0; c < 3; ++c) {
    base[c] =
        unit_factor(src_, pbr.baseColorFactor[c], where + "/pbrMetallicRoughness/baseColorFactor");
  }
  k.base_color = TexturedRgb(Vec3(base[0], base[1], base[2]));
  if (pbr.baseColorTexture.index >= 0) {
    k.base_color.texture = textured(pbr.baseColorTexture, ColourSpace::srgb,
                                    where + "/pbrMetallicRoughness/baseColorTexture");
  }
  k.metallic =
      unit_factor(src_, pbr.metallicFactor, where + "/pbrMetallicRoughness/metallicFactor");
  k.roughness =
      unit_factor(src_, pbr.roughnessFactor, where + "/pbrMetallicRoughness/roughnessFactor");
  if (pbr.metallicRoughnessTexture.index >= 0) {
    const int32_t t = textured(pbr.metallicRoughnessTexture, ColourSpace::linear,
                               where + "/pbrMetallicRoughness/metallicRoughnessTexture");
    // The specification's channels: metalness in blue, roughness in green.
    k.metallic.texture = t;
    k.metallic.channel = TextureChannel::kB;
    k.roughness.texture = t;
    k.roughness.channel = TextureChannel::kG;
  }

  const auto& ext = g.extensions;
  if (auto it = ext.find("KHR_materials_ior"); it != ext.end()) {
    const std::string at = where + "/extensions/KHR_materials_ior";
    const double ior = ext_number(src_, it->second, "ior", 1.5, at);
    // The extension allows 0 for "no refraction" (a thin surface); the closest rayfarm has is
    // an index of 1 (no Fresnel reflection at all).
    if (ior == 0.0) {
      k.ior = 1.f;
    } else if (ior >= 1.0 && ior <= 10.0) {
      k.ior = static_cast<float>(ior);
    } else {
      src_.fail(at + "/ior", "must be 0 or lie in [1, 10], is " + std::to_string(ior));
    }
  }
  if (auto it = ext.find("KHR_materials_transmission"); it != ext.end()) {
    const std::string at = where + "/extensions/KHR_materials_transmission";
    k.transmission = unit_factor(src_, ext_number(src_, it->second, "transmissionFactor", 0.0, at),
                                 at + "/transmissionFactor");
    if (it->second.Has("transmissionTexture")) {
      const tinygltf::Value& info = it->second.Get("transmissionTexture");
      const std::string tat = at + "/transmissionTexture";
      if (!info.IsObject() || !info.Has("index") || !info.Get("index").IsInt())
        src_.fail(tat, "expected a texture info with an integer index");
      const int set = texcoord_set(src_, info, 0, tat);
      note_texcoord(set, tat);
      const tinygltf::ExtensionMap none;
      k.transmission.texture =
          texture(info.Get("index").GetNumberAsInt(), set, none, ColourSpace::linear, tat);
      k.transmission.channel = TextureChannel::kR;
    }
  }

  // Emission: factor times strength (KHR_materials_emissive_strength), in rayfarm's radiance.
  if (g.emissiveFactor.size() != 3) src_.fail(where + "/emissiveFactor", "expected 3 numbers");
  double strength = 1.0;
  if (auto it = ext.find("KHR_materials_emissive_strength"); it != ext.end()) {
    const std::string at = where + "/extensions/KHR_materials_emissive_strength";
    strength = ext_number(src_, it->second, "emissiveStrength", 1.0, at);
    if (!(strength >= 0.0 && strength <= 1e6))
      src_.fail(at + "/emissiveStrength", "must lie in [0, 1e6]");
  }
  float e[3];
  for (size_t c = 0; c < 3; ++c)
    e[c] = static_cast<float>(unit_factor(src_, g.emissiveFactor[c], where + "/emissiveFactor") *
                              strength);
  m.emission = Vec3(e[0], e[1], e[2]);
  if (g.emissiveTexture.index >= 0) {
    m.emission.texture = textured(g.emissiveTexture, ColourSpace::srgb, where + "/emissiveTexture");
  }
  if (g.normalTexture.index >= 0) {
    NormalMap& map = m.normal_map.emplace();
    map.texture = static_cast<uint32_t>(
        textured(g.normalTexture, ColourSpace::linear, where + "/normalTexture"));
    if (!(std::fabs(g.normalTexture.scale) <= 1e3))
      src_.fail(where + "/normalTexture/scale", "must lie in [-1000, 1000]");
    map.scale = static_cast<float>(g.normalTexture.scale);
  }
  if (g.alphaMode == "MASK" || g.alphaMode == "BLEND") {
    // Coverage: the base colour's alpha times its texture's; MASK: below the cutoff, not there;
    // BLEND: there with that probability.
    m.alpha = TexturedFloat(
        unit_factor(src_, pbr.baseColorFactor[3], where + "/pbrMetallicRoughness/baseColorFactor"));
    if (k.base_color.is_textured()) {
      m.alpha.texture = k.base_color.texture;
      m.alpha.channel = TextureChannel::kA;
    }
    m.alpha_cutoff = 0.5f;
    if (g.alphaMode == "MASK") {
      m.alpha_cutoff = unit_factor(src_, g.alphaCutoff, where + "/alphaCutoff");
    } else {
      m.alpha_blend = true;  // partial coverage: there with probability alpha
    }
    if (m.has_alpha() && m.is_emissive()) {
      src_.warn(where + "/alphaMode", "an emissive surface cannot be cut out; it is opaque");
      m.alpha = TexturedFloat(1.f);
    }
  } else if (g.alphaMode != "OPAQUE" && !g.alphaMode.empty()) {
    src_.fail(where + "/alphaMode", "unknown alpha mode \"" + g.alphaMode + "\"");
  }
  m.two_sided = g.doubleSided;  // emission leaves both sides of a double-sided surface
  m.kind = k;
  if (std::optional<MaterialKind> solid = volume(g, k, where)) m.kind = *solid;
  m.textured = std::visit(
      [](const auto& p) {
        return std::apply(
            [&p](auto... member) { return (false || ... || (p.*member).is_textured()); },
            p.textured());
      },
      m.kind);
  if (texcoord >= 0) texcoords_[index] = texcoord;
  return m;
}

std::optional<MaterialKind> Materials::volume(const tinygltf::Material& g,
                                              const MetallicRoughnessMaterial& k,
                                              const std::string& where) {
  const auto it = g.extensions.find("KHR_materials_volume");
  if (it == g.extensions.end()) return std::nullopt;
  const std::string at = where + "/extensions/KHR_materials_volume";
  const tinygltf::Value& x = it->second;
  const double thickness = ext_number(src_, x, "thicknessFactor", 0.0, at);
  if (!(thickness >= 0.0 && thickness <= 1e17))
    src_.fail(at + "/thicknessFactor", "must lie in [0, 1e17], is " + std::to_string(thickness));
  const double distance =
      ext_number(src_, x, "attenuationDistance", std::numeric_limits<double>::infinity(), at);
  if (x.IsObject() && x.Has("attenuationDistance") && !(distance > 0.0))
    src_.fail(at + "/attenuationDistance", "must be positive, is " + std::to_string(distance));
  bool tinted = false;
  if (x.IsObject() && x.Has("attenuationColor")) {
    const tinygltf::Value& c = x.Get("attenuationColor");
    if (!c.IsArray() || c.ArrayLen() != 3)
      src_.fail(at + "/attenuationColor", "expected 3 numbers");
    for (int i = 0; i < 3; ++i) {
      if (!c.Get(i).IsNumber()) src_.fail(at + "/attenuationColor", "expected 3 numbers");
      tinted |= unit_factor(src_, c.Get(i).GetNumberAsDouble(), at + "/attenuationColor") < 1.f;
    }
  }
  // Without transmission, or on a wholly metallic surface (glTF mixes the metal over the
  // transmitting dielectric), light never enters the volume; with a zero thickness the glTF
  // surface is thin-walled again.
  const bool enters = k.transmission.value > 0.f || k.transmission.is_textured();
  const bool metal = k.metallic.value == 1.f && !k.metallic.is_textured();
  if (thickness == 0.0 || !enters || metal) return std::nullopt;

  if (k.transmission.value < 1.f || k.transmission.is_textured() || k.metallic.value > 0.f ||
      k.metallic.is_textured()) {
    src_.warn(at,
              "the material is read as a solid dielectric that transmits everywhere; its "
              "metallic and diffuse shares (metallicFactor, transmissionFactor below 1, "
              "their textures) are not rendered");
  }
  if (k.roughness.is_textured())
    src_.warn(at,
              "a refracting volume's roughness is roughnessFactor alone; the roughness of "
              "metallicRoughnessTexture is not read");
  // rayfarm has no absorbing media: light inside the volume travels unattenuated. Said once per
  // file, since one file often has many glass materials.
  if (tinted && std::isfinite(distance) && !attenuation_warned_) {
    attenuation_warned_ = true;
    src_.warn(at,
              "attenuationColor and attenuationDistance are ignored: rayfarm has no "
              "absorption inside volumes (base colour still tints each crossing)");
  }
  const float roughness = k.roughness.value;
  if (roughness == 0.f) {
    DielectricMaterial d;
    d.ior = k.ior;
    d.tint = k.base_color;
    return d;
  }
  RoughDielectricMaterial d;
  d.ior = k.ior;
  d.alpha_u = d.alpha_v = roughness * roughness;
  d.tint = k.base_color;
  return d;
}

int32_t Materials::texture(int index, int uv_set, const tinygltf::ExtensionMap& extensions,
                           ColourSpace space, const std::string& where) {
  (void)uv_set;
  const auto& all = src_.model->textures;
  const std::string name = "textures[" + std::to_string(index) + "]";
  if (index < 0 || static_cast<size_t>(index) >= all.size())
    src_.fail(where, name + " does not exist (the file has " + std::to_string(all.size()) + ")");
  const tinygltf::Texture& t = all[static_cast<size_t>(index)];

  ImageTextureOptions options;
  options.origin = UvOrigin::top_left;  // glTF's uv (0, 0) is the image's top-left corner
  if (t.sampler >= 0) {
    if (static_cast<size_t>(t.sampler) >= src_.model->samplers.size())
      src_.fail(name, "sampler " + std::to_string(t.sampler) + " does not exist");
    const tinygltf::Sampler& s = src_.model->samplers[static_cast<size_t>(t.sampler)];
    options.wrap_u = wrap_mode(s.wrapS);
    options.wrap_v = wrap_mode(s.wrapT);
    if (s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST) options.filter = TextureFilter::nearest;
  }
  std::string transform_key;
  if (auto it = extensions.find("KHR_texture_transform"); it != extensions.end()) {
    const std::string at = where + "/extensions/KHR_texture_transform";
    const tinygltf::Value& x = it->second;
    auto pair = [&](const std::string& key, float fallback) -> std::array<float, 2> {
      if (!x.Has(key)) return {fallback, fallback};
      const tinygltf::Value& v = x.Get(key);
      if (!v.IsArray() || v.ArrayLen() != 2 || !v.Get(0).IsNumber() || !v.Get(1).IsNumber())
        src_.fail(at + "/" + key, "expected 2 numbers");
      std::array<float, 2> out{};
      for (int i = 0; i < 2; ++i) {
        const double d = v.Get(i).GetNumberAsDouble();
        if (!(std::fabs(d) <= 1e6)) src_.fail(at + "/" + key, "numbers must lie in [-1e6, 1e6]");
        out[static_cast<size_t>(i)] = static_cast<float>(d);
      }
      return out;
    };
    options.transform.offset = pair("offset", 0.f);
    options.transform.scale = pair("scale", 1.f);
    const double r = ext_number(src_, x, "rotation", 0.0, at);
    if (!(std::fabs(r) <= 1e3)) src_.fail(at + "/rotation", "must lie in [-1000, 1000] radians");
    // The extension turns the UVs counter-clockwise as drawn on the image (v down): u' = cos r u +
    // sin r v, v' = -sin r u + cos r v, UvTransform's own matrix. The extension's GLSL listing has
    // the transpose (a known erratum, KhronosGroup/glTF#1563); its sample model and viewers follow
    // the text, and so does rayfarm.
    options.transform.rotation = static_cast<float>(r);
    // The exact values, not a rounded print: transforms differing in the seventh digit are
    // different textures.
    auto exact = [](double v) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%a,", v);
      return std::string(buf);
    };
    transform_key = exact(options.transform.offset[0]) + exact(options.transform.offset[1]) +
                    exact(options.transform.scale[0]) + exact(options.transform.scale[1]) +
                    exact(r);
  }
  const auto key = std::tuple{index, space, transform_key};
  if (auto it = textures_.find(key); it != textures_.end()) return it->second;

  if (t.source < 0 || static_cast<size_t>(t.source) >= src_.model->images.size()) {
    src_.fail(name, t.source < 0 ? "has no image (source)"
                                 : "image " + std::to_string(t.source) + " does not exist");
  }
  const tinygltf::Image& img = src_.model->images[static_cast<size_t>(t.source)];
  TextureDesc desc;
  desc.name = "gltf:" + name;
  desc.kind = TextureDesc::Kind::kImage;
  // An image file is named by its path, so that a file several glTF images share loads once; an
  // embedded image by the glTF file and its index.
  desc.file =
      img.bufferView < 0 && !img.uri.empty() && img.uri.rfind("data:", 0) != 0
          ? (gltf_file_.parent_path() / img.uri).lexically_normal()
          : fs::path(gltf_file_.generic_string() + "#images[" + std::to_string(t.source) + "]");
  desc.space = space;
  desc.options = options;
  desc.image = image(t.source, name);
  const auto scene_index = static_cast<int32_t>(scene_.textures.size());
  scene_.textures.push_back(std::move(desc));
  textures_[key] = scene_index;
  return scene_index;
}

std::shared_ptr<const DecodedImage> Materials::image(int index, const std::string& where) {
  if (images_ == SceneImages::kSkip) return nullptr;
  if (auto it = decoded_.find(index); it != decoded_.end()) return it->second;
  const tinygltf::Image& img = src_.model->images[static_cast<size_t>(index)];
  const std::string name = "images[" + std::to_string(index) + "]";
  std::vector<uint8_t> view;
  std::span<const uint8_t> bytes;
  if (img.bufferView >= 0) {
    view = buffer_view_bytes(src_, img.bufferView, name);
    bytes = view;
  } else if (auto it = bytes_.find(index); it != bytes_.end()) {
    bytes = it->second;
  } else {
    src_.fail(where,
              name + (img.uri.empty() ? " has no data" : " \"" + img.uri + "\" could not be read"));
  }
  DecodedImage decoded;
  try {
    decoded = decode_image(bytes, src_.display + ": " + name);
  } catch (const SceneError& e) {
    throw SceneError(std::string(e.what()) + " (read by " + where + ")");
  }
  decoded_bytes_ +=
      decoded.is_float() ? decoded.floats.size() * sizeof(float) : decoded.bytes.size();
  if (decoded_bytes_ > kMaxSceneTextureBytes)
    src_.fail(name, "the file's decoded images exceed the limit of 2 GiB");
  std::shared_ptr<const DecodedImage> out;
  if (images_ == SceneImages::kKeep) out = std::make_shared<const DecodedImage>(std::move(decoded));
  decoded_[index] = out;
  return out;
}

}  // namespace rayfarm::gltf
