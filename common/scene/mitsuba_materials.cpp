// Mitsuba 3 BSDFs and textures as rayfarm materials (docs/mitsuba.md, "BSDFs", "Textures").
// Wrappers (twosided, mask, bumpmap, normalmap) become the surface properties every rayfarm
// material may carry; what rayfarm cannot render as Mitsuba would is an error naming the element.
#include <cmath>

#include "common/limits.h"
#include "common/scene/mitsuba_reader.h"
#include "common/scene/spectra.h"
#include "common/util/text.h"

namespace rayfarm::mitsuba {
namespace fs = std::filesystem;

namespace {

constexpr float kAirIor = 1.000277f;  // Mitsuba's "air", its default exterior

std::shared_ptr<const DecodedImage> decode(Context& ctx, const XmlElement& at,
                                           const fs::path& rel) {
  if (auto it = ctx.decoded.find(rel); it != ctx.decoded.end()) return it->second;
  uint64_t bytes = 0;
  const At place(at, ctx.scene, "filename");
  auto out =
      decode_scene_image(place.node, ctx.files.scene_dir, rel, ctx.images, "texture image", &bytes);
  ctx.decoded_bytes += bytes;
  if (ctx.decoded_bytes > kMaxSceneTextureBytes) {
    at.fail(printable(rel.generic_string()) + ": the scene's images hold " +
            human_bytes(ctx.decoded_bytes) + " of samples with this one, more than the limit of " +
            human_bytes(kMaxSceneTextureBytes));
  }
  ctx.decoded[rel] = out;
  return out;
}

/// Mitsuba's to_uv (a 2D affine map in its own UVs) composed after the map from the shape's
/// stored UVs to Mitsuba's. `image`: then also the flip of v that rayfarm's bottom-left image
/// origin undoes (Mitsuba's images have v = 0 at the top). Images keep the bottom-left origin
/// rather than take the top-left one so that a normal map's y stays n x dp/du, as Mitsuba's does.
UvTransform uv_map(Props& p, UvKind uv, bool image) {
  const Transform t = p.transform("to_uv");
  double a = t.at(0, 0), b = t.at(0, 1), c = t.at(0, 3), d = t.at(1, 0), e = t.at(1, 1),
         f = t.at(1, 3);
  if (uv == UvKind::kMeshFile) {  // (u, v) -> (u, 1 - v) first
    c += b;
    b = -b;
    f += e;
    e = -e;
  }
  if (image) {  // v -> 1 - v last
    d = -d;
    e = -e;
    f = 1.0 - f;
  }
  UvTransform out;
  out.matrix = std::array<float, 6>{float(a), float(b), float(c), float(d), float(e), float(f)};
  return out;
}

TextureWrap wrap_of(const XmlElement& at, const std::string& mode) {
  if (mode == "repeat") return TextureWrap::repeat;
  if (mode == "mirror") return TextureWrap::mirror;
  if (mode == "clamp") return TextureWrap::clamp;
  at.fail("wrap_mode \"" + printable(mode, 32) + "\": expected repeat, mirror or clamp");
}

float ior_of(Props& p, std::string_view name, float fallback) {
  const XmlElement* e = p.find(name);
  if (e == nullptr) return fallback;
  if (e->tag == "string") {
    const std::string& v = value_of(*e);
    if (auto ior = named_ior(v)) return *ior;
    e->fail("unknown material \"" + printable(v, 40) + "\"; known: " + named_ior_choices());
  }
  const float v = static_cast<float>(p.number(name, fallback));
  if (!(v >= 1.f && v <= 10.f)) e->fail("an index of refraction must lie in [1, 10]");
  return v;
}

/// int_ior / ext_ior as the one ratio rayfarm's dielectrics take.
float relative_ior(Props& p, float interior) {
  const float ratio = ior_of(p, "int_ior", interior) / ior_of(p, "ext_ior", kAirIor);
  if (ratio == 1.f) p.element().fail("int_ior equals ext_ior: the interface is invisible");
  return ratio;
}

MicrofacetType distribution_of(Props& p) {
  const std::string d = p.string("distribution", "beckmann");
  if (d == "beckmann") return MicrofacetType::kBeckmann;
  if (d == "ggx") return MicrofacetType::kGgx;
  p.find("distribution")
      ->fail("distribution \"" + printable(d, 32) + "\": expected beckmann or ggx");
}

/// alpha, or alpha_u and alpha_v (default 0.1).
std::pair<TexturedFloat, TexturedFloat> roughness_of(Context& ctx, Props& p, UvKind uv) {
  auto one = [&](std::string_view name) {
    const Colour c = p.scalar(name, 0.1f);
    if (!c.texture && !(c.value.x >= 0.f && c.value.x <= 1.f))
      p.find(name)->fail("a roughness must lie in [0, 1]");
    return textured_float(ctx, c, uv);
  };
  if (p.has("alpha")) return {one("alpha"), one("alpha")};
  return {one("alpha_u"), one("alpha_v")};
}

void require_white(Props& p, std::string_view name) {
  const Colour c = p.colour(name, Vec3(1.f), SpectrumRole::reflectance);
  if (c.texture != nullptr || c.value != Vec3(1.f))
    p.find(name)->fail("only the default 1 is supported for " + std::string(name));
}

MaterialKind conductor(Context& ctx, Props& p, UvKind uv, bool rough) {
  RoughConductorMaterial m;
  const std::string name = p.string("material", p.has("eta") || p.has("k") ? "" : "none");
  if (!name.empty() && (p.has("eta") || p.has("k")))
    p.find("material")->fail("give either material or eta and k");
  if (name == "none") {
    m.use_f0 = true;
    m.f0 = TexturedRgb(Vec3(1.f));
  } else if (!name.empty()) {
    const auto ior = named_conductor(name);
    if (!ior)
      p.find("material")
          ->fail("unknown conductor \"" + printable(name, 40) +
                 "\"; known: " + named_conductor_choices());
    m.eta = ior->eta;
    m.k = ior->k;
  } else {
    auto constant = [&](std::string_view key, float fallback) {
      const Colour c = p.colour(key, Vec3(fallback), SpectrumRole::unbounded);
      if (c.texture != nullptr) p.find(key)->fail("a textured eta or k is not supported");
      return c.value;
    };
    m.eta = constant("eta", 0.f);
    m.k = constant("k", 1.f);
  }
  m.specular_reflectance =
      textured_rgb(ctx, p.colour("specular_reflectance", Vec3(1.f), SpectrumRole::reflectance), uv);
  if (rough) {
    m.distribution = distribution_of(p);
    std::tie(m.alpha_u, m.alpha_v) = roughness_of(ctx, p, uv);
  } else {
    m.alpha_u = TexturedFloat(0.f);
    m.alpha_v = TexturedFloat(0.f);
  }
  p.finish({"sample_visible"});
  return m;
}

MaterialKind dielectric(Context& ctx, Props& p, UvKind uv, const std::string& type) {
  const float ior = relative_ior(p, 1.5046f);  // Mitsuba's default interior: BK7
  require_white(p, "specular_reflectance");
  const TexturedRgb tint = textured_rgb(
      ctx, p.colour("specular_transmittance", Vec3(1.f), SpectrumRole::reflectance), uv);
  if (type == "thindielectric") {
    p.finish();
    return ThinDielectricMaterial{ior, tint};
  }
  if (type == "dielectric") {
    p.finish();
    return DielectricMaterial{ior, tint};
  }
  RoughDielectricMaterial m;
  m.ior = ior;
  m.tint = tint;
  m.distribution = distribution_of(p);
  std::tie(m.alpha_u, m.alpha_v) = roughness_of(ctx, p, uv);
  p.finish({"sample_visible"});
  return m;
}

MaterialKind plastic(Context& ctx, Props& p, UvKind uv, bool rough) {
  PlasticMaterial m;
  m.diffuse_reflectance =
      textured_rgb(ctx, p.colour("diffuse_reflectance", Vec3(0.5f), SpectrumRole::reflectance), uv);
  require_white(p, "specular_reflectance");
  m.ior = relative_ior(p, 1.49f);  // Mitsuba's default interior: polypropylene
  m.nonlinear = p.boolean("nonlinear", false);
  if (rough) {
    m.distribution = distribution_of(p);
    const Colour alpha = p.scalar("alpha", 0.1f);
    if (alpha.texture != nullptr)
      p.find("alpha")->fail("a textured roughplastic alpha is not supported");
    if (!(alpha.value.x >= 0.f && alpha.value.x <= 1.f))
      p.find("alpha")->fail("alpha must lie in [0, 1]");
    m.alpha = TexturedFloat(alpha.value.x);
  }
  p.finish({"sample_visible"});
  return m;
}

/// Whether a kind reads any texture.
bool reads_texture(const MaterialKind& kind) {
  return std::visit(
      [](const auto& k) {
        bool any = false;
        std::apply([&](auto... f) { ((any = any || (k.*f).is_textured()), ...); }, k.textured());
        return any;
      },
      kind);
}

/// Fills `m` from `bsdf`, unwrapping twosided, mask, bumpmap and normalmap.
void convert(Context& ctx, const XmlElement& bsdf, UvKind uv, Material& m, int depth) {
  if (depth > 8) bsdf.fail("BSDFs nest more than 8 deep");
  Props p(bsdf, ctx);
  const std::string type = type_of(bsdf);
  auto nested = [&]() -> const XmlElement& {
    const auto inner = p.plugins("bsdf");
    if (inner.size() != 1)
      bsdf.fail("expects exactly one nested <bsdf>, got " + std::to_string(inner.size()));
    return *inner[0];
  };
  if (type == "twosided") {
    const auto inner = p.plugins("bsdf");
    if (inner.empty() || inner.size() > 2) bsdf.fail("expects one nested <bsdf> (or two)");
    if (inner.size() == 2 && inner[0] != inner[1])
      bsdf.fail("a twosided BSDF with a different back side is not supported");
    p.finish();
    convert(ctx, *inner[0], uv, m, depth + 1);
    m.one_sided = false;
    return;
  }
  if (type == "mask") {
    // Mitsuba's mask lets a ray through with probability 1 - opacity: partial coverage.
    const Colour opacity = p.scalar("opacity", 0.5f);
    const XmlElement& inner = nested();
    p.finish();
    if (opacity.texture == nullptr && !(opacity.value.x >= 0.f && opacity.value.x <= 1.f))
      bsdf.fail("opacity must lie in [0, 1]");
    if (m.alpha_blend) bsdf.fail("a mask inside a mask is not supported");
    m.alpha = textured_float(ctx, opacity, uv);
    m.alpha_blend = true;
    convert(ctx, inner, uv, m, depth + 1);
    return;
  }
  if (type == "bumpmap" || type == "normalmap") {
    const auto textures = p.plugins("texture");
    const XmlElement* tex = textures.size() == 1 ? textures[0] : p.find(type);
    if (textures.size() > 1 || tex == nullptr) bsdf.fail("expects one nested <texture>");
    const float scale = type == "bumpmap" ? static_cast<float>(p.number("scale", 1.0)) : 1.f;
    const XmlElement& inner = nested();
    p.finish();
    if (type_of(*tex) == "rawconstant") {
      // A constant height is flat; a constant normal (0.5, 0.5, z) is the surface's own.
      Props c(*tex, ctx);
      if (type == "normalmap") {
        const auto v = c.point("value");
        if (!v || v->x != 0.5 || v->y != 0.5 || !(v->z > 0.5))
          tex->fail("a constant normal map other than (0.5, 0.5, z) is not supported");
      } else {
        (void)c.find("value");
      }
      c.finish();
    } else if (type == "bumpmap") {
      m.bump_map = BumpMap{static_cast<uint32_t>(texture_of(ctx, *tex, uv, false)), scale};
    } else {
      m.normal_map = NormalMap{static_cast<uint32_t>(texture_of(ctx, *tex, uv, false)), 1.f};
    }
    convert(ctx, inner, uv, m, depth + 1);
    return;
  }
  if (type == "diffuse") {
    DiffuseMaterial d;
    d.albedo =
        textured_rgb(ctx, p.colour("reflectance", Vec3(0.5f), SpectrumRole::reflectance), uv);
    p.finish();
    m.kind = d;
  } else if (type == "conductor" || type == "roughconductor") {
    m.kind = conductor(ctx, p, uv, type == "roughconductor");
  } else if (type == "dielectric" || type == "roughdielectric" || type == "thindielectric") {
    m.kind = dielectric(ctx, p, uv, type);
  } else if (type == "plastic" || type == "roughplastic") {
    m.kind = plastic(ctx, p, uv, type == "roughplastic");
  } else {
    bsdf.fail("the BSDF \"" + printable(type, 40) +
              "\" is not supported (docs/mitsuba.md lists the BSDFs rayfarm reads)");
  }
  m.textured = reads_texture(m.kind);
}

}  // namespace

int32_t texture_of(Context& ctx, const XmlElement& tex, UvKind uv, bool as_colour) {
  const auto key = std::make_pair(&tex, static_cast<UvKind>(int(uv) | (as_colour ? 2 : 0)));
  if (auto it = ctx.textures.find(key); it != ctx.textures.end()) return it->second;
  Props p(tex, ctx);
  const std::string type = type_of(tex);
  TextureDesc desc;
  desc.name = tex.where();
  desc.options.transform = uv_map(p, uv, type == "bitmap");
  if (type == "bitmap") {
    const std::string* file = p.find("filename") ? &value_of(*p.find("filename")) : nullptr;
    if (file == nullptr) tex.fail("a bitmap needs a filename");
    desc.kind = TextureDesc::Kind::kImage;
    desc.file = resolve_mitsuba_file(ctx.files, tex, *file);
    desc.image = decode(ctx, tex, desc.file);
    desc.space = p.boolean("raw", false) ? ColourSpace::linear : ColourSpace::from_file;
    const std::string filter = p.string("filter_type", "bilinear");
    if (filter == "nearest")
      desc.options.filter = TextureFilter::nearest;
    else if (filter != "bilinear")
      p.find("filter_type")->fail("expected bilinear or nearest");
    const TextureWrap wrap = wrap_of(tex, p.string("wrap_mode", "repeat"));
    desc.options.wrap_u = desc.options.wrap_v = wrap;
    p.finish({"format", "accel"});
  } else if (type == "checkerboard") {
    desc.kind = TextureDesc::Kind::kCheckerboard;
    const Colour c0 = p.colour("color0", Vec3(0.4f), SpectrumRole::reflectance),
                 c1 = p.colour("color1", Vec3(0.2f), SpectrumRole::reflectance);
    if (c0.texture != nullptr || c1.texture != nullptr)
      tex.fail("textured checkerboard colours are not supported");
    // Mitsuba's colour lookups give color0 where both UVs are in the same half of their unit,
    // its scalar lookups where they are not; rayfarm's checkerboard is the scalar one.
    desc.color0 = as_colour ? c1.value : c0.value;
    desc.color1 = as_colour ? c0.value : c1.value;
    p.finish();
  } else {
    tex.fail("the texture \"" + printable(type, 40) +
             "\" is not supported (bitmap and checkerboard are)");
  }
  const auto index = static_cast<int32_t>(ctx.scene.textures.size());
  ctx.scene.textures.push_back(std::move(desc));
  ctx.textures[key] = index;
  return index;
}

TexturedRgb textured_rgb(Context& ctx, const Colour& c, UvKind uv) {
  if (c.texture == nullptr) return TexturedRgb(c.value);
  TexturedRgb t(Vec3(1.f));
  t.texture = texture_of(ctx, *c.texture, uv, true);
  return t;
}

TexturedFloat textured_float(Context& ctx, const Colour& c, UvKind uv) {
  if (c.texture == nullptr) return TexturedFloat(c.value.x);
  TexturedFloat t(1.f);
  t.texture = texture_of(ctx, *c.texture, uv, false);
  t.channel = TextureChannel::kMean;
  return t;
}

uint32_t material_of(Context& ctx, const XmlElement* bsdf, UvKind uv) {
  const auto key = std::make_pair(bsdf, uv);
  if (auto it = ctx.materials.find(key); it != ctx.materials.end()) return it->second;
  Material m;
  m.one_sided = true;      // Mitsuba's BSDFs are black from behind unless twosided
  m.shading_sided = true;  // behind the shading normal's horizon, that is
  if (bsdf == nullptr) {
    m.name = "default diffuse";
    m.kind = DiffuseMaterial{TexturedRgb(Vec3(0.5f))};
  } else {
    const std::string* id = bsdf->find("id");
    m.name = id != nullptr ? *id : bsdf->where();
    convert(ctx, *bsdf, uv, m, 0);
    if (std::holds_alternative<DielectricMaterial>(m.kind) ||
        std::holds_alternative<RoughDielectricMaterial>(m.kind) ||
        std::holds_alternative<ThinDielectricMaterial>(m.kind))
      m.one_sided = false;  // glass has no back to be black
  }
  const auto index = static_cast<uint32_t>(ctx.scene.materials.size());
  ctx.scene.materials.push_back(std::move(m));
  ctx.materials[key] = index;
  return index;
}

}  // namespace rayfarm::mitsuba
