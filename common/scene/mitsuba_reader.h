#pragma once
// Shared by the Mitsuba 3 scene reader's parts (mitsuba_*.cpp): the reading context and typed
// access to a plugin element's parameters. Internal to common/scene.
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "common/math/transform.h"
#include "common/scene/json_reader.h"
#include "common/scene/mitsuba_xml.h"
#include "common/scene/scene.h"
#include "common/scene/spectra.h"
#include "common/scene/texture_reader.h"

namespace rayfarm::mitsuba {

/// How a shape's texture coordinates relate to Mitsuba's: a mesh file read with flip_tex_coords
/// (Mitsuba's default for OBJ, not for PLY) stores (u, 1 - v_mitsuba); other mesh files and the
/// shapes that rayfarm builds store Mitsuba's own (u, v). Textures are looked up in Mitsuba's
/// (u, v), so a material is converted once per kind of shape it is used on.
enum class UvKind : uint8_t { kMeshFile = 0, kNative = 1 };

/// What Mitsuba 3's RGB variants make of its emitters' default spectrum, the D65 white point
/// (scaled so that a constant emitter of radiance 1 has luminance 1): read from its render of a
/// constant emitter (tests/data/mitsuba/.../test_constant_ref_rgb.exr, every background pixel).
/// An emitter's number or one-valued spectrum is this white times the value.
inline constexpr Vec3 kEmitterWhite{1.00108f, 0.99971f, 0.99970f};

/// Everything the reader's parts share.
struct Context {
  Context(Scene& s, XmlFiles& f, SceneImages i) : scene(s), files(f), images(i) {}
  Scene& scene;
  XmlFiles& files;
  SceneImages images;
  std::map<std::string, const XmlElement*> ids;  ///< every element with an id
  std::set<std::string> warned;                  ///< kinds of warning already given
  std::map<std::filesystem::path, std::shared_ptr<const DecodedImage>> decoded;
  uint64_t decoded_bytes = 0;
  std::map<std::pair<const XmlElement*, UvKind>, int32_t> textures;
  std::map<std::pair<const XmlElement*, UvKind>, uint32_t> materials;
  /// The spheres of each shapegroup (by group index), in the group's space: each instance places
  /// a copy of them in the scene. The spheres of the group being read go to `group_spheres_open`.
  std::map<uint32_t, std::vector<Sphere>> group_spheres;
  std::vector<Sphere>* group_spheres_open = nullptr;
  /// Width over height of the images projectors cast, by file (each decoded for it once).
  std::map<std::filesystem::path, double> aspects;
  uint64_t instanced_spheres = 0;

  /// Adds `what` to the scene's warnings once per `kind` (e.g. "sampler").
  void warn_once(const std::string& kind, const XmlElement& at, const std::string& what);
  /// The element a <ref id="..."> names (itself when it is not a ref).
  const XmlElement& deref(const XmlElement& e) const;
  /// A scene_json node placed at `e`, for the shared readers that report through one.
  std::string where(const XmlElement& e) const { return e.where(); }
};

/// A scene_json node that reports at an XML element, for the readers shared with the JSON format
/// (transforms, images): their messages then name the XML file, line and element.
struct At {
  scene_json::Json null;
  scene_json::Context context;
  scene_json::Node node;
  At(const XmlElement& e, Scene& scene, const char* what)
      : context{e.where(), &scene.warnings}, node(null, context, what) {}
};

/// A colour parameter: a constant, or a texture element (bitmap, checkerboard).
struct Colour {
  Vec3 value{0.f};
  const XmlElement* texture = nullptr;
};

/// The named parameters of one plugin element (<float name="x" .../> and the like), read by
/// type; finish() reports the ones nobody read.
class Props {
 public:
  Props(const XmlElement& e, Context& ctx);

  const XmlElement& element() const { return e_; }
  /// The child named `name` (dereferenced), marked as read; null when absent.
  const XmlElement* find(std::string_view name);
  bool has(std::string_view name) const;

  double number(std::string_view name, double fallback);
  int64_t integer(std::string_view name, int64_t fallback, int64_t lo, int64_t hi);
  bool boolean(std::string_view name, bool fallback);
  std::string string(std::string_view name, const std::string& fallback);
  std::optional<WideVec3> point(std::string_view name);  ///< <point> or <vector>
  /// <transform name=...>: its operations composed in order; the identity when absent.
  Transform transform(std::string_view name);
  /// An RGB, a spectrum (converted as `role` says: docs/mitsuba.md), a float (grey) or a
  /// texture. A reflectance must lie in [0, 1]; other roles must not be negative.
  Colour colour(std::string_view name, const Vec3& fallback, SpectrumRole role);
  /// A number or a texture (its value is the factor 1).
  Colour scalar(std::string_view name, float fallback);

  /// Unnamed plugin children of tag `tag` (refs dereferenced), marked as read.
  std::vector<const XmlElement*> plugins(std::string_view tag);

  /// Fails on a named parameter that was not read, unless listed in `ignored` (a warning then,
  /// once per plugin type and name: parameters that change nothing rayfarm renders).
  void finish(std::initializer_list<std::string_view> ignored = {});

 private:
  const XmlElement& e_;
  Context& ctx_;
  std::vector<bool> read_;
};

/// Numbers in a value attribute: separated by commas and/or white space.
std::vector<double> parse_numbers(const XmlElement& at, const std::string& text);
/// The value attribute of `e`.
const std::string& value_of(const XmlElement& e);
/// The type attribute of `e` ("" when absent).
std::string type_of(const XmlElement& e);

/// The material that `bsdf` (null: Mitsuba's default, a diffuse of reflectance 0.5) describes for
/// shapes with `uv` coordinates, added to the scene once; returns its index.
uint32_t material_of(Context& ctx, const XmlElement* bsdf, UvKind uv);
/// The texture `tex` describes, added once per UV kind; fails on kinds rayfarm lacks.
/// `as_colour`: looked up as a colour (not as a number), which flips a checkerboard's colours.
int32_t texture_of(Context& ctx, const XmlElement& tex, UvKind uv, bool as_colour);
/// A textured or constant RGB parameter from a Colour.
TexturedRgb textured_rgb(Context& ctx, const Colour& c, UvKind uv);
/// A textured or constant scalar parameter from a Colour (its mean channel).
TexturedFloat textured_float(Context& ctx, const Colour& c, UvKind uv);

/// Reads the <shape> elements (meshes, spheres, built-in shapes, groups, instances) and their
/// area emitters.
/// Meshes go to `meshes` (the world's, or a group's when `in_group`); `groups` maps each
/// shapegroup read so far to its index.
void read_shape(Context& ctx, const XmlElement& shape, std::vector<TriangleMesh>& meshes,
                bool in_group, std::map<const XmlElement*, uint32_t>& groups);
/// Reads an <emitter> outside any shape (point, spot, directional, constant, envmap).
void read_emitter(Context& ctx, const XmlElement& emitter);

}  // namespace rayfarm::mitsuba
