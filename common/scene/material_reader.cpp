// One reader per material kind (docs/scene-format.md, "Materials"): its keys, then its
// parameters, each range checked where it is read so that the message names the value.
#include "common/scene/material_reader.h"

#include <sstream>
#include <variant>

namespace rayfarm::scene_json {
namespace {

// What every kind accepts besides its own parameters (read by read_surface()).
#define SURFACE_KEYS "one_sided", "normal_map", "bump_map", "opacity", "alpha_cutoff", "coverage"

void read_params(const Node& n, DiffuseMaterial& d, const TextureReader& tex) {
  n.allow_keys({"type", "albedo", "emission", "two_sided", SURFACE_KEYS});
  if (auto a = n.find("albedo")) d.albedo = tex.reflectance(*a);
}

void read_params(const Node& n, PhongMaterial& p, const TextureReader& tex) {
  n.allow_keys({"type", "kd", "ks", "exponent", "emission", "two_sided", SURFACE_KEYS});
  p.kd = read_reflectance(n.require("kd"));
  p.ks = read_reflectance(n.require("ks"));
  p.exponent = read_non_negative(n.require("exponent"));
  const Vec3 total = p.kd + p.ks;
  for (int i = 0; i < 3; ++i) {
    if (total[i] > 1.f + 1e-6f) {
      n.fail("kd + ks is " + std::to_string(total[i]) + " in channel " + std::to_string(i) +
             "; it must not exceed 1 (energy conservation)");
    }
  }
}

void read_params(const Node& n, MirrorMaterial& m, const TextureReader& tex) {
  n.allow_keys({"type", "reflectance", "emission", "two_sided", SURFACE_KEYS});
  if (auto r = n.find("reflectance")) m.reflectance = tex.reflectance(*r);
}

void read_params(const Node& n, DielectricMaterial& d, const TextureReader& tex) {
  n.allow_keys({"type", "ior", "tint", "emission", "two_sided", SURFACE_KEYS});
  if (auto ior = n.find("ior")) d.ior = read_positive(*ior);
  if (auto tint = n.find("tint")) d.tint = tex.reflectance(*tint);
}

/// A roughness: in [0, 1] (alpha above 1 is a surface rougher than any the model describes).
TexturedFloat read_alpha(const Node& n, const TextureReader& tex) {
  return tex.number(n, 0.f, 1.f);
}

/// "alpha" (isotropic) or "alpha_u" with "alpha_v", not both; unchanged when neither is given.
void read_alphas(const Node& n, TexturedFloat& alpha_u, TexturedFloat& alpha_v,
                 const TextureReader& tex) {
  const auto alpha = n.find("alpha");
  const auto u = n.find("alpha_u"), v = n.find("alpha_v");
  if (alpha && (u || v)) (u ? *u : *v).fail("give either \"alpha\" or \"alpha_u\" and \"alpha_v\"");
  if (alpha) alpha_u = alpha_v = read_alpha(*alpha, tex);
  if (u || v) {
    if (!u) n.fail("\"alpha_v\" needs \"alpha_u\"");
    if (!v) n.fail("\"alpha_u\" needs \"alpha_v\"");
    alpha_u = read_alpha(*u, tex);
    alpha_v = read_alpha(*v, tex);
  }
}

/// "distribution": the microfacet normals' distribution, "ggx" or "beckmann".
MicrofacetType read_distribution(const Node& n) {
  const std::string name = read_string(n);
  if (name == "ggx") return MicrofacetType::kGgx;
  if (name == "beckmann") return MicrofacetType::kBeckmann;
  n.fail("unknown distribution " + as_written(n.json()) + "; expected ggx or beckmann");
}

void read_params(const Node& n, RoughConductorMaterial& c, const TextureReader& tex) {
  n.allow_keys({"type", "eta", "k", "f0", "alpha", "alpha_u", "alpha_v", "distribution",
                "specular_reflectance", "emission", "two_sided", SURFACE_KEYS});
  const auto f0 = n.find("f0");
  if (f0) {
    if (auto e = n.find("eta")) e->fail("give either \"f0\" or \"eta\" and \"k\"");
    if (auto k = n.find("k")) k->fail("give either \"f0\" or \"eta\" and \"k\"");
    c.use_f0 = true;
    c.f0 = tex.reflectance(*f0);
  }
  if (auto e = n.find("eta")) {
    c.eta = read_vec3(*e);
    for (int i = 0; i < 3; ++i)
      if (!(c.eta[i] > 0.f)) e->fail("every channel of eta must be > 0");
  }
  if (auto k = n.find("k")) {
    c.k = read_vec3(*k);
    for (int i = 0; i < 3; ++i)
      if (!(c.k[i] >= 0.f)) k->fail("every channel of k must be >= 0");
  }
  read_alphas(n, c.alpha_u, c.alpha_v, tex);
  if (auto d = n.find("distribution")) c.distribution = read_distribution(*d);
  if (auto s = n.find("specular_reflectance")) c.specular_reflectance = tex.reflectance(*s);
}

void read_params(const Node& n, RoughDielectricMaterial& d, const TextureReader& tex) {
  n.allow_keys({"type", "ior", "alpha", "alpha_u", "alpha_v", "distribution", "tint", "emission",
                "two_sided", SURFACE_KEYS});
  if (auto ior = n.find("ior")) d.ior = read_positive(*ior);
  read_alphas(n, d.alpha_u, d.alpha_v, tex);
  if (auto dist = n.find("distribution")) d.distribution = read_distribution(*dist);
  if (auto tint = n.find("tint")) d.tint = tex.reflectance(*tint);
}

void read_params(const Node& n, ThinDielectricMaterial& d, const TextureReader& tex) {
  n.allow_keys({"type", "ior", "tint", "emission", "two_sided", SURFACE_KEYS});
  if (auto ior = n.find("ior")) d.ior = read_positive(*ior);
  if (auto tint = n.find("tint")) d.tint = tex.reflectance(*tint);
}

void read_params(const Node& n, PlasticMaterial& p, const TextureReader& tex) {
  n.allow_keys({"type", "diffuse_reflectance", "ior", "alpha", "distribution", "nonlinear",
                "emission", "two_sided", SURFACE_KEYS});
  if (auto r = n.find("diffuse_reflectance")) p.diffuse_reflectance = tex.reflectance(*r);
  if (auto ior = n.find("ior")) p.ior = read_positive(*ior);
  if (auto a = n.find("alpha")) p.alpha = read_alpha(*a, tex);
  if (auto d = n.find("distribution")) p.distribution = read_distribution(*d);
  if (auto nl = n.find("nonlinear")) p.nonlinear = read_bool(*nl);
}

void read_params(const Node& n, MetallicRoughnessMaterial& m, const TextureReader& tex) {
  n.allow_keys({"type", "base_color", "metallic", "roughness", "ior", "transmission", "emission",
                "two_sided", SURFACE_KEYS});
  if (auto b = n.find("base_color")) m.base_color = tex.reflectance(*b);
  if (auto v = n.find("metallic")) m.metallic = tex.number(*v, 0.f, 1.f);
  if (auto r = n.find("roughness")) m.roughness = tex.number(*r, 0.f, 1.f);
  if (auto ior = n.find("ior")) m.ior = read_positive(*ior);
  if (auto t = n.find("transmission")) m.transmission = tex.number(*t, 0.f, 1.f);
}

/// "roughplastic": plastic whose coating must be rough (alpha 0.1 unless given).
void read_rough_plastic(const Node& n, PlasticMaterial& p, const TextureReader& tex) {
  p.alpha = 0.1f;
  read_params(n, p, tex);
  if (!p.alpha.is_textured() && !(p.alpha.value > 0.f))
    n.require("alpha").fail("roughplastic needs alpha > 0 (plastic is the smooth one)");
}

/// "conductor": the smooth conductor, the same keys less the roughness.
void read_smooth_conductor(const Node& n, RoughConductorMaterial& c, const TextureReader& tex) {
  n.allow_keys(
      {"type", "eta", "k", "f0", "specular_reflectance", "emission", "two_sided", SURFACE_KEYS});
  read_params(n, c, tex);
  c.alpha_u = c.alpha_v = 0.f;
}

template <size_t I = 0>
bool read_kind(const Node& n, const std::string& type, MaterialKind& out,
               const TextureReader& tex) {
  if constexpr (I < std::variant_size_v<MaterialKind>) {
    using Params = std::variant_alternative_t<I, MaterialKind>;
    if (type != Params::kName) return read_kind<I + 1>(n, type, out, tex);
    read_params(n, out.emplace<I>(), tex);
    return true;
  } else {
    return false;
  }
}

template <size_t I = 0>
std::string kind_names() {
  const std::string name = std::variant_alternative_t<I, MaterialKind>::kName;
  if constexpr (I + 1 < std::variant_size_v<MaterialKind>) {
    return name + ", " + kind_names<I + 1>();
  } else {
    return name;
  }
}

}  // namespace

bool read_material_kind(const Node& n, const std::string& type, MaterialKind& out,
                        const TextureReader& tex) {
  if (type == "conductor") {
    read_smooth_conductor(n, out.emplace<RoughConductorMaterial>(), tex);
    return true;
  }
  if (type == "roughplastic") {
    read_rough_plastic(n, out.emplace<PlasticMaterial>(), tex);
    return true;
  }
  return read_kind(n, type, out, tex);
}

namespace {

/// The texture a normal or bump map reads, which holds data rather than colour: one whose colour
/// space comes from the file is read linear; one declared sRGB is refused.
uint32_t read_data_texture(const Node& n, const TextureReader& tex,
                           std::vector<TextureDesc>& textures) {
  const Node ref = n.require("texture");
  const int32_t index = tex.texture_index(ref);
  TextureDesc& desc = textures[static_cast<size_t>(index)];
  if (desc.space == ColourSpace::srgb)
    ref.fail("texture \"" + desc.name +
             "\" is declared sRGB; normal and bump maps hold data and must be read linear");
  desc.space = ColourSpace::linear;
  return static_cast<uint32_t>(index);
}

bool is_transmissive(const MaterialKind& kind) {
  if (const auto* m = std::get_if<MetallicRoughnessMaterial>(&kind))
    return m->transmission.is_textured() || m->transmission.value > 0.f;
  return std::holds_alternative<DielectricMaterial>(kind) ||
         std::holds_alternative<RoughDielectricMaterial>(kind) ||
         std::holds_alternative<ThinDielectricMaterial>(kind);
}

}  // namespace

void read_surface(const Node& n, Material& m, const TextureReader& tex,
                  std::vector<TextureDesc>& textures) {
  if (auto e = n.find("emission")) m.emission = tex.radiance(*e);
  if (auto s = n.find("two_sided")) m.two_sided = read_bool(*s);
  if (auto s = n.find("one_sided")) {
    m.one_sided = read_bool(*s);
    if (m.one_sided && is_transmissive(m.kind))
      s->fail("one_sided needs an opaque material; a " + std::string(material_kind_name(m.kind)) +
              " one transmits light from behind");
  }
  const auto read_map = [&](const Node& map, auto& out) {
    map.allow_keys({"texture", "scale"});
    out.texture = read_data_texture(map, tex, textures);
    if (auto s = map.find("scale")) out.scale = read_float(*s);
  };
  if (auto map = n.find("normal_map")) read_map(*map, m.normal_map.emplace());
  if (auto map = n.find("bump_map")) read_map(*map, m.bump_map.emplace());
  if (m.normal_map && m.bump_map)
    n.child("bump_map").fail("give either \"normal_map\" or \"bump_map\", not both");
  if (auto o = n.find("opacity")) m.alpha = tex.number(*o, 0.f, 1.f);
  if (auto c = n.find("coverage")) {
    const std::string mode = read_string(*c);
    if (mode == "blend") {
      m.alpha_blend = true;
    } else if (mode != "cutoff") {
      c->fail("coverage " + as_written(c->json()) + ": expected \"cutoff\" or \"blend\"");
    }
  }
  if (auto c = n.find("alpha_cutoff")) {
    m.alpha_cutoff = read_float(*c);
    if (!(m.alpha_cutoff >= 0.f && m.alpha_cutoff <= 1.f))
      c->fail("alpha_cutoff must lie in [0, 1]");
  }
  if (m.has_alpha() && m.is_emissive())
    n.child("opacity").fail("an emitter cannot have cut-outs (opacity below alpha_cutoff)");
}

std::string material_type_names() { return kind_names() + ", conductor, roughplastic"; }

}  // namespace rayfarm::scene_json
