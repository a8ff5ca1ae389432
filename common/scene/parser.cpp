// The JSON scene format (docs/scene-format.md). Every value is read through a Node, which knows
// the file and the JSON pointer of the value, so every message can say where the problem is.
#include "common/scene/parser.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <initializer_list>
#include <map>
#include <string_view>
#include <variant>

#include "common/scene/obj_loader.h"

namespace rayfarm {
namespace fs = std::filesystem;

namespace {

using Json = nlohmann::ordered_json;  // keeps materials in file order

constexpr std::uintmax_t kMaxSceneFileBytes = std::uintmax_t{64} << 20;
constexpr int kMaxNesting = 64;
constexpr double kMaxAbsNumber = 1e30;
/// Largest coordinate or length of geometry: every point of a scene (a quad's far corner, a
/// sphere's surface, a thin lens) then stays well inside the range that Embree traces, +-1.8e18.
constexpr double kMaxCoordinate = 1e17;
constexpr int64_t kMaxFilmSide = 16384;
constexpr int64_t kMaxFilmPixels = int64_t{1} << 26;
constexpr int64_t kMaxSpp = int64_t{1} << 24;
constexpr int64_t kMaxDepth = 1024;
constexpr size_t kMaxStringInMessage = 40;

/// Thrown by the parse callback when the nesting limit is reached.
struct NestingTooDeep {};

/// Printable ASCII only, so that a message never carries the broken bytes it complains about.
std::string printable(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7F) c = '?';
  }
  return out;
}

/// "string \"x\"", "number 1.5", "an array": what a value is, for "expected ..., got ...".
std::string describe(const Json& value) {
  switch (value.type()) {
    case Json::value_t::null:
      return "null";
    case Json::value_t::boolean:
      return value.get<bool>() ? "true" : "false";
    case Json::value_t::object:
      return "an object";
    case Json::value_t::array:
      return "an array";
    case Json::value_t::string: {
      const auto& s = value.get_ref<const std::string&>();
      if (s.size() <= kMaxStringInMessage) return "string " + printable(Json(s).dump());
      return "string " + printable(Json(s.substr(0, kMaxStringInMessage)).dump()) + "...";
    }
    default:
      return "number " + value.dump();
  }
}

/// A string value as written, in quotes ("\"plastic\""); other values as describe() has them.
std::string as_written(const Json& value) {
  return value.is_string() ? describe(value).substr(std::string("string ").size())
                           : describe(value);
}

std::string escape_pointer_token(const std::string& key) {
  std::string out;
  for (char c : key) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}

/// The file being read and the warnings found so far.
struct Context {
  std::string file;
  std::vector<std::string>* warnings;
};

/// A JSON value with its place (file and JSON pointer) for messages.
class Node {
 public:
  Node(const Json& value, const Context& context, std::string pointer)
      : value_(&value), context_(&context), pointer_(std::move(pointer)) {}

  const Json& json() const { return *value_; }
  std::string where() const {
    return context_->file + ": " +
           (pointer_.empty() ? std::string("(top level)") : printable(pointer_));
  }
  [[noreturn]] void fail(const std::string& what) const { throw SceneError(where() + ": " + what); }
  void warn(const std::string& what) const { context_->warnings->push_back(where() + ": " + what); }

  /// This node as an object; fails otherwise.
  const Json& object() const {
    if (!value_->is_object()) fail("expected an object, got " + describe(*value_));
    return *value_;
  }
  /// This node as an array; fails otherwise.
  const Json& array() const {
    if (!value_->is_array()) fail("expected an array, got " + describe(*value_));
    return *value_;
  }
  Node child(const std::string& key) const {
    return Node(object().at(key), *context_, pointer_ + "/" + escape_pointer_token(key));
  }
  Node child(size_t index) const {
    return Node(array().at(index), *context_, pointer_ + "/" + std::to_string(index));
  }
  std::optional<Node> find(const std::string& key) const {
    if (!object().contains(key)) return std::nullopt;
    return child(key);
  }
  Node require(const std::string& key) const {
    if (!object().contains(key)) fail("missing key \"" + key + "\"");
    return child(key);
  }
  /// Warns about every key of this object that is not in `known`.
  void allow_keys(std::initializer_list<std::string_view> known) const {
    for (const auto& [key, value] : object().items()) {
      bool found = false;
      for (std::string_view k : known) found = found || k == key;
      if (!found) child(key).warn("unknown key \"" + printable(key) + "\" ignored");
    }
  }

 private:
  const Json* value_;
  const Context* context_;
  std::string pointer_;
};

// ---- values ----------------------------------------------------------------------------------

double read_number(const Node& n) {
  const Json& v = n.json();
  if (!v.is_number()) n.fail("expected a number, got " + describe(v));
  const double x = v.get<double>();
  if (!std::isfinite(x) || std::abs(x) > kMaxAbsNumber) {
    n.fail("number " + v.dump() + " is out of range (magnitude at most 1e30)");
  }
  return x;
}

float read_float(const Node& n) { return static_cast<float>(read_number(n)); }

float read_positive(const Node& n) {
  const float x = read_float(n);
  if (!(x > 0.f)) n.fail("must be positive, got " + n.json().dump());
  return x;
}

float read_non_negative(const Node& n) {
  const float x = read_float(n);
  if (x < 0.f) n.fail("must not be negative, got " + n.json().dump());
  return x;
}

int64_t read_integer(const Node& n, int64_t lo, int64_t hi) {
  const Json& v = n.json();
  if (!v.is_number_integer()) n.fail("expected an integer, got " + describe(v));
  // Non-negative literals parse as unsigned, which may exceed int64_t.
  const bool fits = !v.is_number_unsigned() || v.get<uint64_t>() <= static_cast<uint64_t>(hi);
  const bool in_range = fits && v.get<int64_t>() >= lo && v.get<int64_t>() <= hi;
  if (!in_range) {
    n.fail("must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi) +
           ", got " + v.dump());
  }
  return v.get<int64_t>();
}

uint64_t read_unsigned(const Node& n) {
  const Json& v = n.json();
  if (!v.is_number_integer() || (!v.is_number_unsigned() && v.get<int64_t>() < 0)) {
    n.fail("expected an unsigned integer, got " + describe(v));
  }
  return v.get<uint64_t>();
}

bool read_bool(const Node& n) {
  if (!n.json().is_boolean()) n.fail("expected true or false, got " + describe(n.json()));
  return n.json().get<bool>();
}

std::string read_string(const Node& n) {
  if (!n.json().is_string()) n.fail("expected a string, got " + describe(n.json()));
  return n.json().get<std::string>();
}

Vec3 read_vec3(const Node& n) {
  const Json& v = n.array();
  if (v.size() != 3)
    n.fail("expected an array of 3 numbers, got " + std::to_string(v.size()) + " values");
  return {read_float(n.child(0)), read_float(n.child(1)), read_float(n.child(2))};
}

/// A number of geometry (a coordinate or a length): magnitude at most kMaxCoordinate.
float read_coordinate(const Node& n) {
  const float x = read_float(n);
  if (std::abs(double(x)) > kMaxCoordinate) {
    n.fail("coordinate " + n.json().dump() +
           " is beyond 1e17, the largest that the renderer handles (rays are traced within "
           "+-1.8e18)");
  }
  return x;
}

/// A point or vector of geometry: 3 numbers of magnitude at most kMaxCoordinate.
Vec3 read_point(const Node& n) {
  (void)read_vec3(n);
  return {read_coordinate(n.child(0)), read_coordinate(n.child(1)), read_coordinate(n.child(2))};
}

/// A positive length of geometry, at most kMaxCoordinate.
float read_length(const Node& n) {
  (void)read_positive(n);
  return read_coordinate(n);
}

/// An RGB reflectance: every channel in [0, 1].
Vec3 read_reflectance(const Node& n) {
  const Vec3 c = read_vec3(n);
  for (size_t i = 0; i < 3; ++i) {
    if (c[int(i)] < 0.f || c[int(i)] > 1.f) {
      n.child(i).fail("a reflectance must lie in [0, 1], got " + n.child(i).json().dump());
    }
  }
  return c;
}

/// An RGB radiance or intensity: every channel >= 0.
Vec3 read_radiance(const Node& n) {
  const Vec3 c = read_vec3(n);
  for (size_t i = 0; i < 3; ++i) read_non_negative(n.child(i));
  return c;
}

/// Length of the cross product, in double so that coordinates up to 1e30 cannot overflow.
double cross_length(const Vec3& a, const Vec3& b) {
  const double x = double(a.y) * b.z - double(a.z) * b.y;
  const double y = double(a.z) * b.x - double(a.x) * b.z;
  const double z = double(a.x) * b.y - double(a.y) * b.x;
  return std::sqrt(x * x + y * y + z * z);
}

double length_d(const Vec3& a) {
  return std::sqrt(double(a.x) * a.x + double(a.y) * a.y + double(a.z) * a.z);
}

// ---- the scene -------------------------------------------------------------------------------

/// Fills a Scene from the parsed JSON, one top-level section at a time.
class SceneReader {
 public:
  SceneReader(Scene* scene, const Context& context, fs::path folder)
      : scene_(*scene), context_(context), folder_(std::move(folder)) {}

  void read(const Node& root) {
    root.allow_keys(
        {"format", "camera", "film", "materials", "shapes", "lights", "background", "render"});
    if (auto n = root.find("format")) read_format(*n);
    read_camera(root.require("camera"));
    read_film(root.require("film"));
    if (auto n = root.find("materials")) read_materials(*n);
    if (auto n = root.find("shapes")) read_shapes(*n);
    if (auto n = root.find("lights")) read_lights(*n);
    if (auto n = root.find("background")) scene_.background = read_radiance(*n);
    if (auto n = root.find("render")) read_render(*n);
  }

 private:
  static void read_format(const Node& n) {
    const int64_t format = read_integer(n, 1, INT64_MAX);
    if (format > kSceneFormatVersion) {
      n.fail("scene format " + std::to_string(format) + " is newer than format " +
             std::to_string(kSceneFormatVersion) + ", the newest this build reads");
    }
  }

  void read_camera(const Node& n) {
    n.allow_keys({"type", "eye", "look_at", "up", "fov_y", "aperture_radius", "focus_distance"});
    if (auto type = n.find("type"); type && read_string(*type) != "perspective") {
      type->fail("unknown camera type " + as_written(type->json()) + "; expected \"perspective\"");
    }
    Camera& c = scene_.camera;
    c.eye = read_point(n.require("eye"));
    c.look_at = read_point(n.require("look_at"));
    if (auto up = n.find("up")) c.up = read_point(*up);
    const Node fov = n.require("fov_y");
    c.fov_y_deg = read_float(fov);
    if (!(c.fov_y_deg > 0.f && c.fov_y_deg < 180.f)) fov.fail("fov_y must lie in (0, 180) degrees");
    if (auto a = n.find("aperture_radius")) {
      (void)read_non_negative(*a);
      c.aperture_radius = read_coordinate(*a);
    }
    if (auto f = n.find("focus_distance")) c.focus_distance = read_length(*f);
    check_view(n, c);
  }

  static void check_view(const Node& n, const Camera& c) {
    const Vec3 forward = c.look_at - c.eye;
    const double distance = length_d(forward);
    if (distance == 0.0) n.child("look_at").fail("look_at equals eye: no view direction");
    const double up = length_d(c.up);
    if (up != 0.0 && cross_length(forward, c.up) > 1e-6 * distance * up) return;
    if (auto given = n.find("up")) given->fail("up is zero or parallel to the view direction");
    n.fail("the default up [0, 1, 0] is parallel to the view direction; give \"up\"");
  }

  void read_film(const Node& n) {
    n.allow_keys({"width", "height"});
    const int64_t width = read_integer(n.require("width"), 1, kMaxFilmSide);
    const int64_t height = read_integer(n.require("height"), 1, kMaxFilmSide);
    if (width * height > kMaxFilmPixels) {
      n.fail("film " + std::to_string(width) + "x" + std::to_string(height) + " has " +
             std::to_string(width * height) + " pixels, more than the limit of " +
             std::to_string(kMaxFilmPixels) + " (2^26)");
    }
    scene_.film = {static_cast<uint32_t>(width), static_cast<uint32_t>(height)};
  }

  // ---- materials ----

  void read_materials(const Node& n) {
    for (const auto& [name, value] : n.object().items()) {
      const Node m = n.child(name);
      if (name.empty()) m.fail("a material name must not be empty");
      add_material(read_material(m, name));
    }
  }

  /// Adds a material, or returns the index of the one already named so.
  uint32_t add_material(Material m) {
    const auto [it, added] = material_index_.try_emplace(m.name, uint32_t(scene_.materials.size()));
    if (added) scene_.materials.push_back(std::move(m));
    return it->second;
  }

  static Material read_material(const Node& n, const std::string& name) {
    Material m;
    m.name = name;
    const Node type = n.require("type");
    if (!read_kind(n, read_string(type), m.kind)) {
      type.fail("unknown material type " + as_written(type.json()) + "; expected one of " +
                kind_names());
    }
    if (auto e = n.find("emission")) m.emission = read_radiance(*e);
    if (auto s = n.find("two_sided")) m.two_sided = read_bool(*s);
    return m;
  }

  /// Reads the parameters of the kind named `kind` into `out`; false when no kind has that name.
  template <size_t I = 0>
  static bool read_kind(const Node& n, const std::string& kind, MaterialKind& out) {
    if constexpr (I < std::variant_size_v<MaterialKind>) {
      using Params = std::variant_alternative_t<I, MaterialKind>;
      if (kind != Params::kName) return read_kind<I + 1>(n, kind, out);
      read_params(n, out.emplace<I>());
      return true;
    } else {
      return false;
    }
  }

  /// "diffuse, phong, ...": every kind's name, for messages.
  template <size_t I = 0>
  static std::string kind_names() {
    const std::string name = std::variant_alternative_t<I, MaterialKind>::kName;
    if constexpr (I + 1 < std::variant_size_v<MaterialKind>) {
      return name + ", " + kind_names<I + 1>();
    } else {
      return name;
    }
  }

  // One reader per material kind: its keys, then its parameters.

  static void read_params(const Node& n, DiffuseMaterial& d) {
    n.allow_keys({"type", "albedo", "emission", "two_sided"});
    if (auto a = n.find("albedo")) d.albedo = read_reflectance(*a);
  }

  static void read_params(const Node& n, PhongMaterial& p) {
    n.allow_keys({"type", "kd", "ks", "exponent", "emission", "two_sided"});
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

  static void read_params(const Node& n, MirrorMaterial& m) {
    n.allow_keys({"type", "reflectance", "emission", "two_sided"});
    if (auto r = n.find("reflectance")) m.reflectance = read_reflectance(*r);
  }

  static void read_params(const Node& n, DielectricMaterial& d) {
    n.allow_keys({"type", "ior", "tint", "emission", "two_sided"});
    if (auto ior = n.find("ior")) d.ior = read_positive(*ior);
    if (auto tint = n.find("tint")) d.tint = read_reflectance(*tint);
  }

  uint32_t material_ref(const Node& n) const {
    const std::string name = read_string(n);
    if (auto it = material_index_.find(name); it != material_index_.end()) return it->second;
    std::string known;
    for (const auto& [key, index] : material_index_) known += (known.empty() ? "" : ", ") + key;
    n.fail("unknown material " + as_written(n.json()) +
           (known.empty() ? "; no materials are defined" : "; defined: " + printable(known)));
  }

  // ---- shapes ----

  void read_shapes(const Node& n) {
    for (size_t i = 0; i < n.array().size(); ++i) {
      const Node shape = n.child(i);
      const Node type = shape.require("type");
      const std::string kind = read_string(type);
      const std::string origin = "shapes[" + std::to_string(i) + "]";
      if (kind == "mesh")
        read_mesh(shape);
      else if (kind == "sphere")
        read_sphere(shape);
      else if (kind == "quad")
        read_quad(shape, origin);
      else if (kind == "triangle")
        read_triangle(shape, origin);
      else
        type.fail("unknown shape type " + as_written(type.json()) +
                  "; expected one of mesh, sphere, quad, triangle");
    }
  }

  void read_sphere(const Node& n) {
    n.allow_keys({"type", "center", "radius", "material"});
    Sphere s;
    s.center = read_point(n.require("center"));
    s.radius = read_length(n.require("radius"));
    s.material = material_ref(n.require("material"));
    scene_.spheres.push_back(s);
  }

  void read_quad(const Node& n, const std::string& origin) {
    n.allow_keys({"type", "corner", "edge1", "edge2", "material"});
    const Vec3 c = read_point(n.require("corner"));
    const Vec3 e1 = read_point(n.require("edge1"));
    const Vec3 e2 = read_point(n.require("edge2"));
    const uint32_t material = material_ref(n.require("material"));
    if (cross_length(e1, e2) == 0.0) {
      n.warn("the quad has zero area and is dropped");
      return;
    }
    // Both triangles' front faces, (v1-v0) x (v2-v0), point along edge1 x edge2.
    add_triangles(origin, {c, c + e1, c + e1 + e2, c + e2}, {0, 1, 2, 0, 2, 3}, material);
  }

  void read_triangle(const Node& n, const std::string& origin) {
    n.allow_keys({"type", "vertices", "material"});
    const Node vertices = n.require("vertices");
    if (vertices.array().size() != 3) {
      vertices.fail("expected 3 vertices, got " + std::to_string(vertices.array().size()));
    }
    const Vec3 a = read_point(vertices.child(0));
    const Vec3 b = read_point(vertices.child(1));
    const Vec3 c = read_point(vertices.child(2));
    const uint32_t material = material_ref(n.require("material"));
    if (cross_length(b - a, c - a) == 0.0) {
      n.warn("the triangle has zero area and is dropped");
      return;
    }
    add_triangles(origin, {a, b, c}, {0, 1, 2}, material);
  }

  void add_triangles(const std::string& origin, std::vector<Vec3> positions,
                     std::vector<uint32_t> indices, uint32_t material) {
    TriangleMesh mesh;
    mesh.materials.assign(indices.size() / 3, material);
    mesh.positions = std::move(positions);
    mesh.indices = std::move(indices);
    mesh.origin = origin;
    scene_.meshes.push_back(std::move(mesh));
  }

  void read_mesh(const Node& n) {
    n.allow_keys({"type", "file", "material"});
    const fs::path relative = mesh_path(n.require("file"));
    std::optional<uint32_t> material;
    if (auto m = n.find("material")) material = material_ref(*m);
    ObjMesh obj = load_obj(folder_, relative);
    for (const fs::path& file : obj.files) add_referenced(file);
    for (std::string& w : obj.warnings) scene_.warnings.push_back(std::move(w));
    std::vector<uint32_t> remap;
    for (Material& m : obj.materials)
      remap.push_back(material ? *material : add_material(std::move(m)));
    for (uint32_t& index : obj.mesh.materials) index = remap.at(index);
    if (obj.mesh.triangle_count() == 0) {
      n.warn("the mesh has no triangles");
      return;
    }
    scene_.meshes.push_back(std::move(obj.mesh));
  }

  /// The mesh file, relative to the scene's folder; it must stay inside and exist.
  fs::path mesh_path(const Node& n) const {
    const std::string reference = read_string(n);
    std::string why;
    const auto relative = resolve_scene_path(fs::path(), reference, &why);
    if (!relative) n.fail(as_written(n.json()) + ": " + why);
    const fs::path full = folder_ / *relative;
    std::error_code error;
    if (!fs::exists(full, error)) {
      n.fail("mesh file " + as_written(n.json()) + " not found (looked for " +
             printable(full.string()) + ")");
    }
    return *relative;
  }

  void add_referenced(const fs::path& file) {
    for (const fs::path& known : scene_.referenced) {
      if (known == file) return;
    }
    scene_.referenced.push_back(file);
  }

  // ---- lights and render settings ----

  void read_lights(const Node& n) {
    for (size_t i = 0; i < n.array().size(); ++i) {
      const Node light = n.child(i);
      const Node type = light.require("type");
      if (read_string(type) != "point") {
        type.fail("unknown light type " + as_written(type.json()) + "; expected \"point\"");
      }
      light.allow_keys({"type", "position", "intensity"});
      scene_.point_lights.push_back(
          {read_point(light.require("position")), read_radiance(light.require("intensity"))});
    }
  }

  void read_render(const Node& n) {
    n.allow_keys({"spp", "max_depth", "integrator", "seed"});
    RenderSettings& r = scene_.render;
    if (auto spp = n.find("spp")) r.spp = static_cast<uint32_t>(read_integer(*spp, 1, kMaxSpp));
    if (auto d = n.find("max_depth"))
      r.max_depth = static_cast<uint32_t>(read_integer(*d, 0, kMaxDepth));
    if (auto i = n.find("integrator")) {
      const auto type = parse_integrator(read_string(*i));
      if (!type)
        i->fail("unknown integrator " + as_written(i->json()) + "; expected naive, nee or mis");
      r.integrator = *type;
    }
    if (auto seed = n.find("seed")) r.seed = read_unsigned(*seed);
  }

  Scene& scene_;
  const Context& context_;
  fs::path folder_;
  std::map<std::string, uint32_t> material_index_;
};

/// Parses JSON (comments allowed) with at most kMaxNesting levels of arrays and objects.
Json parse_json(const std::string& text, const std::string& file) {
  const Json::parser_callback_t limit = [](int depth, Json::parse_event_t event, Json&) {
    const bool opens =
        event == Json::parse_event_t::object_start || event == Json::parse_event_t::array_start;
    if (opens && depth >= kMaxNesting) throw NestingTooDeep{};
    return true;
  };
  try {
    return Json::parse(text, limit, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const NestingTooDeep&) {
    throw SceneError(file + ": invalid JSON: arrays and objects nested more than " +
                     std::to_string(kMaxNesting) + " levels deep");
  } catch (const Json::parse_error& e) {
    const std::string what = e.what();
    throw SceneError(file + ": invalid JSON (byte " + std::to_string(e.byte) +
                     "): " + printable(what.substr(what.find(']') + 2)));
  } catch (const Json::exception& e) {
    const std::string what = e.what();
    throw SceneError(file + ": invalid JSON: " + printable(what.substr(what.find(']') + 2)));
  }
}

}  // namespace

Scene load_scene(const fs::path& file) {
  const std::string name = file.string();
  const Json root = parse_json(read_text_file(file, kMaxSceneFileBytes, name), name);
  Scene scene;
  scene.source = file;
  const Context context{name, &scene.warnings};
  const Node top(root, context, "");
  top.object();
  SceneReader(&scene, context, file.parent_path()).read(top);
  return scene;
}

}  // namespace rayfarm
