#include "common/scene/texture_reader.h"

#include <cstdint>
#include <cstdio>
#include <span>

#include "common/image/decode_image.h"
#include "common/limits.h"
#include "common/util/read_file.h"
#include "common/util/text.h"

namespace rayfarm {
namespace fs = std::filesystem;
using namespace scene_json;  // NOLINT(google-build-using-namespace): the JSON readers

namespace {

std::string format_number(float v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", double(v));
  return text;
}

/// One of `names` (the enum's values in order); fails naming them all otherwise.
template <class E, size_t N>
E read_choice(const Node& n, const char* const (&names)[N]) {
  const std::string value = read_string(n);
  std::string all;
  for (size_t i = 0; i < N; ++i) {
    if (value == names[i]) return static_cast<E>(i);
    all += std::string(i ? ", " : "") + names[i];
  }
  n.fail("unknown value " + as_written(n.json()) + "; expected one of " + all);
}

std::array<float, 2> read_vec2(const Node& n) {
  if (n.json().is_number()) {
    const float v = read_float(n);
    return {v, v};
  }
  if (n.array().size() != 2) n.fail("expected a number or an array of 2 numbers");
  return {read_float(n.child(0)), read_float(n.child(1))};
}

UvTransform read_uv_transform(const Node& n) {
  n.allow_keys({"offset", "scale", "rotation"});
  UvTransform t;
  if (auto o = n.find("offset")) t.offset = read_vec2(*o);
  if (auto s = n.find("scale")) t.scale = read_vec2(*s);
  if (auto r = n.find("rotation")) t.rotation = read_float(*r) * (3.14159265358979323846f / 180.f);
  return t;
}

}  // namespace

void TextureReader::read(const Node& n, std::vector<TextureDesc>& out,
                         std::vector<fs::path>& referenced) {
  for (const auto& [name, value] : n.object().items()) {
    const Node t = n.child(name);
    if (name.empty()) t.fail("a texture name must not be empty");
    TextureDesc desc;
    desc.name = name;
    const std::string type = read_string(t.require("type"));
    if (auto uv = t.find("uv_transform")) desc.options.transform = read_uv_transform(*uv);
    if (type == "image") {
      t.allow_keys({"type", "file", "color_space", "filter", "wrap", "wrap_u", "wrap_v",
                    "uv_origin", "uv_transform"});
      const Node file = t.require("file");
      std::string why;
      const auto relative = resolve_scene_path(fs::path(), read_string(file), &why);
      if (!relative) file.fail(as_written(file.json()) + ": " + why);
      desc.file = *relative;
      if (auto c = t.find("color_space"))
        desc.space = read_choice<ColourSpace>(*c, {"auto", "srgb", "linear"});
      if (auto f = t.find("filter"))
        desc.options.filter = read_choice<TextureFilter>(*f, {"bilinear", "nearest"});
      static const char* const kWraps[] = {"repeat", "mirror", "clamp"};
      if (auto w = t.find("wrap"))
        desc.options.wrap_u = desc.options.wrap_v = read_choice<TextureWrap>(*w, kWraps);
      if (auto w = t.find("wrap_u")) desc.options.wrap_u = read_choice<TextureWrap>(*w, kWraps);
      if (auto w = t.find("wrap_v")) desc.options.wrap_v = read_choice<TextureWrap>(*w, kWraps);
      if (auto o = t.find("uv_origin"))
        desc.options.origin = read_choice<UvOrigin>(*o, {"bottom_left", "top_left"});
      desc.image = image(file, desc.file);
      bool known = false;
      for (const fs::path& r : referenced) known = known || r == desc.file;
      if (!known) referenced.push_back(desc.file);
    } else if (type == "checkerboard") {
      t.allow_keys({"type", "color0", "color1", "uv_transform"});
      if (auto c = t.find("color0")) desc.color0 = read_radiance(*c);
      if (auto c = t.find("color1")) desc.color1 = read_radiance(*c);
      desc.kind = TextureDesc::Kind::kCheckerboard;
    } else {
      t.child("type").fail("unknown texture type " + as_written(t.child("type").json()) +
                           "; expected image or checkerboard");
    }
    index_[name] = static_cast<int32_t>(out.size());
    out.push_back(std::move(desc));
  }
}

std::shared_ptr<const DecodedImage> decode_scene_image(const Node& n, const fs::path& folder,
                                                       const fs::path& file, SceneImages images,
                                                       const char* what, uint64_t* sample_bytes) {
  if (images == SceneImages::kSkip) return nullptr;
  const fs::path full = folder / file;
  std::string bytes;
  try {
    bytes = read_whole_file(full, kMaxTextureFileBytes);
  } catch (const FileReadError& e) {
    n.fail(std::string(what) + " " + printable(full.string()) + ": " + e.what());
  }
  try {
    const auto* data = reinterpret_cast<const uint8_t*>(bytes.data());
    DecodedImage image = decode_image(std::span<const uint8_t>(data, bytes.size()), full.string());
    if (sample_bytes != nullptr)
      *sample_bytes = image.bytes.size() + image.floats.size() * sizeof(float);
    if (images == SceneImages::kKeep) return std::make_shared<const DecodedImage>(std::move(image));
  } catch (const SceneError& e) {
    n.fail(e.what());
  }
  return nullptr;
}

std::shared_ptr<const DecodedImage> TextureReader::image(const Node& n, const fs::path& file) {
  if (auto it = decoded_.find(file); it != decoded_.end()) return it->second;
  uint64_t bytes = 0;
  auto decoded = decode_scene_image(n, folder_, file, images_, "texture image", &bytes);
  decoded_bytes_ += bytes;
  if (decoded_bytes_ > sample_budget_) {
    n.fail(printable(file.string()) + ": the scene's texture images hold " +
           human_bytes(decoded_bytes_) + " of samples with this one, more than the limit of " +
           human_bytes(sample_budget_));
  }
  decoded_[file] = decoded;
  return decoded;
}

int32_t TextureReader::texture_ref(const Node& n) const {
  const std::string name = read_string(n);
  if (auto it = index_.find(name); it != index_.end()) return it->second;
  std::string known;
  for (const auto& [key, index] : index_) known += (known.empty() ? "" : ", ") + key;
  n.fail("unknown texture " + as_written(n.json()) +
         (known.empty() ? "; no textures are defined" : "; defined: " + printable(known)));
}

TexturedRgb TextureReader::colour_texture(const Node& n) const {
  if (!n.json().contains("texture"))
    n.fail(
        "expected an array of 3 numbers or {\"texture\": NAME}, got an object without \"texture\"");
  n.allow_keys({"texture", "scale"});
  TexturedRgb p(Vec3(1.f));
  p.texture = texture_ref(n.require("texture"));
  return p;
}

TexturedRgb TextureReader::reflectance(const Node& n) const {
  if (!n.json().is_object()) return read_reflectance(n);
  TexturedRgb p = colour_texture(n);
  ++textured_reads_;
  if (auto s = n.find("scale")) {
    if (s->json().is_number()) {
      const float v = read_float(*s);
      if (!(v >= 0.f && v <= 1.f)) s->fail("the scale must lie in [0, 1]");
      p.value = Vec3(v);
    } else {
      p.value = read_reflectance(*s);
    }
  }
  return p;
}

TexturedRgb TextureReader::radiance(const Node& n) const {
  if (!n.json().is_object()) return read_radiance(n);
  TexturedRgb p = colour_texture(n);
  if (auto s = n.find("scale"))
    p.value = s->json().is_number() ? Vec3(read_non_negative(*s)) : read_radiance(*s);
  return p;
}

TexturedFloat TextureReader::number(const Node& n, float lo, float hi) const {
  auto in_range = [&](const Node& at, float v) {
    if (!(v >= lo && v <= hi))
      at.fail("expected a number in [" + format_number(lo) + ", " + format_number(hi) + "], got " +
              as_written(at.json()));
    return v;
  };
  if (!n.json().is_object()) return in_range(n, read_float(n));
  if (!n.json().contains("texture"))
    n.fail("expected a number or {\"texture\": NAME}, got an object without \"texture\"");
  n.allow_keys({"texture", "channel", "scale"});
  TexturedFloat p(1.f);
  p.texture = texture_ref(n.require("texture"));
  ++textured_reads_;
  if (auto c = n.find("channel"))
    p.channel = read_choice<TextureChannel>(*c, {"r", "g", "b", "a", "mean"});
  if (auto s = n.find("scale")) p.value = read_non_negative(*s);
  return p;
}

}  // namespace rayfarm
