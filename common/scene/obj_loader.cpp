// OBJ meshes. Every line is checked as it is read (bytes, numbers, indices against the vertices
// defined so far), so that a bad file is reported as FILE:LINE, and the mesh is built in the same
// pass: vertices as they come, faces fan-triangulated, zero-area triangles dropped.
#include "common/scene/obj_loader.h"

#include <charconv>
#include <cmath>
#include <set>
#include <string_view>
#include <system_error>

#include "common/limits.h"
#include "common/math/wide.h"
#include "common/scene/corner_weld.h"
#include "common/scene/mtl_loader.h"

namespace rayfarm {
namespace fs = std::filesystem;
using scene_text::in_quotes;
using scene_text::Where;

namespace {

constexpr size_t kMaxFaceVertices = 255;  // the most corners of a face read

// ---- OBJ -------------------------------------------------------------------------------------

/// A "usemtl" line: the material its faces use, once the MTL files are loaded.
struct UseMtl {
  Where at;
  std::string name;
  bool after_mtllib = false;  ///< an mtllib line came before it (else its faces get the default)
};

/// What reading an OBJ file found: the mesh, whose material indices point into `usemtls` (or are
/// kNoMaterial), and the MTL files to load.
struct ObjRead {
  TriangleMesh mesh;
  std::vector<MtlLibLine> mtllibs;
  std::vector<UseMtl> usemtls;
  std::vector<bool> usemtl_has_faces;  ///< per usemtl: a face (even a zero-area one) follows it
  bool faces_without_usemtl = false;   ///< a face comes before any usemtl
  std::vector<std::string> warnings;
  size_t dropped = 0;  ///< zero-area triangles
  std::vector<uint32_t> object_starts;  ///< MeshFile::object_starts
  std::vector<std::string> object_names{""};  ///< MeshFile::object_names
};

constexpr uint32_t kNoMaterial = UINT32_MAX;

/// Reads an OBJ file line by line, counting vertices so that every face index can be checked
/// where it is written (relative indices count back from the vertices defined so far).
class ObjReader {
 public:
  ObjRead read(const std::string& text, const std::string& file) {
    scene_text::for_each_line(
        text, file, [this](const Where& at, std::string_view line) { statement(at, line); });
    if (uses_attributes_) weld_attributes();
    return std::move(out_);
  }

 private:
  void statement(const Where& at, std::string_view line) {
    const std::vector<std::string_view> words = scene_text::split_words(line);
    if (words.empty() || words[0].front() == '#') return;
    const std::string_view keyword = words[0];
    if (keyword == "v") {
      scene_text::check_numbers(at, words, 3, 6, "3 coordinates (x y z), optionally w or r g b");
      if (words.size() == 6) at.fail("v: expected 3, 4 or 6 values, got 5");
      float xyz[3];
      for (size_t i = 1; i <= 3; ++i) {
        const double value = *scene_text::parse_number(words[i]);
        if (std::abs(value) > kMaxCoordinate) {
          at.fail("v: coordinate " + in_quotes(words[i]) +
                  " is beyond 1e17, the largest that the renderer handles");
        }
        xyz[i - 1] = static_cast<float>(value);
      }
      out_.mesh.positions.push_back({xyz[0], xyz[1], xyz[2]});
    } else if (keyword == "vt") {
      scene_text::check_numbers(at, words, 1, 3, "1 to 3 texture coordinates");
      const double u = *scene_text::parse_number(words[1]);
      const double v = words.size() > 2 ? *scene_text::parse_number(words[2]) : 0.0;
      texcoords_.push_back({static_cast<float>(u), static_cast<float>(v)});
    } else if (keyword == "vn") {
      scene_text::check_numbers(at, words, 3, 3, "3 normal components");
      const WideVec3 n{*scene_text::parse_number(words[1]), *scene_text::parse_number(words[2]),
                       *scene_text::parse_number(words[3])};
      const double len = length(n);
      if (!(len > 0.0) && !warned_zero_normal_) {
        warned_zero_normal_ = true;
        out_.warnings.push_back(at.message(
            "vn has zero length: faces that use it are shaded with their geometric normal"));
      }
      normals_.push_back(len > 0.0
                             ? Vec3(static_cast<float>(n.x / len), static_cast<float>(n.y / len),
                                    static_cast<float>(n.z / len))
                             : Vec3(0.f));
    } else if (keyword == "f") {
      face(at, words);
    } else if (keyword == "usemtl") {
      if (words.size() < 2) at.fail("usemtl without a material name");
      material_ = static_cast<uint32_t>(out_.usemtls.size());
      out_.usemtls.push_back({at, std::string(words[1]), !out_.mtllibs.empty()});
      out_.usemtl_has_faces.push_back(false);
    } else if (keyword == "mtllib") {
      mtllib(at, line);
    } else if (keyword == "o" || keyword == "g") {
      // A new object or group: its triangles start here, if the one before has any; if not, this
      // line names the one that has not begun. One past the most that split_objects() splits is
      // enough to know the file has too many.
      const auto start = static_cast<uint32_t>(out_.mesh.materials.size());
      const uint32_t previous = out_.object_starts.empty() ? 0 : out_.object_starts.back();
      const std::string_view written = scene_text::rest_after_keyword(line, keyword);
      std::string name = written.empty() ? std::string() : in_quotes(written);  // shortened
      if (start == previous) {
        out_.object_names.back() = std::move(name);
      } else if (out_.object_starts.size() <= kMaxMeshObjects) {
        out_.object_starts.push_back(start);
        out_.object_names.push_back(std::move(name));
      }
    } else if (keyword != "s") {
      ignore(at, keyword);
    }
  }

  void face(const Where& at, const std::vector<std::string_view>& words) {
    const size_t corners = words.size() - 1;
    if (corners < 3)
      at.fail("face with " + std::to_string(corners) + " vertices; at least 3 needed");
    if (corners > kMaxFaceVertices) {
      at.fail("face with " + std::to_string(corners) + " vertices; at most " +
              std::to_string(kMaxFaceVertices) + " are supported");
    }
    if (material_ == kNoMaterial)
      out_.faces_without_usemtl = true;
    else
      out_.usemtl_has_faces[material_] = true;
    corners_.clear();
    for (size_t i = 1; i < words.size(); ++i) corners_.push_back(corner(at, words[i]));
    for (size_t k = 1; k + 1 < corners; ++k) triangle(corners_[0], corners_[k], corners_[k + 1]);
  }

  /// A face corner: its position, texture coordinate and normal (kNone when not given).
  static constexpr uint32_t kNone = UINT32_MAX;
  using Corner = CornerIndices;

  /// One "v", "v/t", "v//n" or "v/t/n" reference.
  Corner corner(const Where& at, std::string_view word) {
    std::vector<std::string_view> parts;
    size_t start = 0;
    for (size_t slash = word.find('/'); slash != std::string_view::npos;
         slash = word.find('/', start)) {
      parts.push_back(word.substr(start, slash - start));
      start = slash + 1;
    }
    parts.push_back(word.substr(start));
    const bool well_formed = parts.size() <= 3 && !parts[0].empty() && !parts.back().empty();
    if (!well_formed) at.fail("malformed face vertex " + in_quotes(word));
    Corner c{static_cast<uint32_t>(index(at, parts[0], out_.mesh.positions.size(), "vertex")),
             kNone, kNone};
    if (parts.size() >= 2 && !parts[1].empty())
      c.t = static_cast<uint32_t>(index(at, parts[1], texcoords_.size(), "texture coordinate"));
    if (parts.size() == 3)
      c.n = static_cast<uint32_t>(index(at, parts[2], normals_.size(), "normal"));
    uses_attributes_ = uses_attributes_ || c.t != kNone || c.n != kNone;
    return c;
  }

  static size_t index(const Where& at, std::string_view word, size_t defined, const char* what) {
    long long value = 0;
    const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
    if (error != std::errc() || end != word.data() + word.size()) {
      at.fail("malformed " + std::string(what) + " index " + in_quotes(word));
    }
    if (value == 0) at.fail(std::string(what) + " index 0 is invalid: OBJ indices start at 1");
    const long long resolved = value > 0 ? value - 1 : static_cast<long long>(defined) + value;
    if (resolved < 0 || resolved >= static_cast<long long>(defined)) {
      at.fail(std::string(what) + " index " + std::to_string(value) +
              " is out of range: " + std::to_string(defined) + " defined so far");
    }
    return static_cast<size_t>(resolved);
  }

  void triangle(const Corner& a, const Corner& b, const Corner& c) {
    const std::vector<Vec3>& p = out_.mesh.positions;
    if (is_zero(edge_cross(p[a.v], p[b.v], p[c.v]))) {
      ++out_.dropped;
      return;
    }
    out_.mesh.indices.insert(out_.mesh.indices.end(), {a.v, b.v, c.v});
    corner_attributes_.insert(corner_attributes_.end(), {a.t, a.n, b.t, b.n, c.t, c.n});
    out_.mesh.materials.push_back(material_);
  }

  /// One vertex per distinct (position, texture coordinate, normal) that faces use, so that each
  /// vertex carries one of each. A corner without a normal gets a zero one (flat shading there);
  /// one without a texture coordinate gets (0, 0).
  void weld_attributes() {
    TriangleMesh& mesh = out_.mesh;
    std::vector<CornerIndices> corners(mesh.indices.size());
    for (size_t i = 0; i < corners.size(); ++i)
      corners[i] = {mesh.indices[i], corner_attributes_[2 * i], corner_attributes_[2 * i + 1]};
    const WeldedCorners welded = weld_corners(corners);
    std::vector<Vec3> positions;
    positions.reserve(welded.first_corner.size());
    const bool any_uv = !texcoords_.empty(), any_normal = !normals_.empty();
    for (uint32_t first : welded.first_corner) {
      const CornerIndices& c = corners[first];
      positions.push_back(mesh.positions[c.v]);
      if (any_uv) mesh.uvs.push_back(c.t == kNone ? Vec2() : texcoords_[c.t]);
      if (any_normal) mesh.normals.push_back(c.n == kNone ? Vec3(0.f) : normals_[c.n]);
    }
    mesh.indices = welded.vertex_of;
    mesh.positions = std::move(positions);
  }

  /// An mtllib line's file names (a backslash keeps a blank in a name).
  void mtllib(const Where& at, std::string_view line) {
    std::vector<std::string> names;
    std::string name;
    const std::string_view rest = scene_text::rest_after_keyword(line, "mtllib");
    for (size_t i = 0; i < rest.size(); ++i) {
      if (rest[i] == '\\' && i + 1 < rest.size() && rest[i + 1] == ' ') {
        name += rest[++i];
      } else if (rest[i] == ' ' || rest[i] == '\t') {
        if (!name.empty()) names.push_back(std::move(name));
        name.clear();
      } else {
        name += rest[i];
      }
    }
    if (!name.empty()) names.push_back(std::move(name));
    if (names.empty()) at.fail("mtllib without a file name");
    out_.mtllibs.push_back({at, std::move(names)});
  }

  void ignore(const Where& at, std::string_view keyword) {
    if (warned_.insert(std::string(keyword)).second) {
      out_.warnings.push_back(
          at.message("statement " + in_quotes(keyword) + " is not supported and is ignored"));
    }
  }

  std::vector<Vec2> texcoords_;
  std::vector<Vec3> normals_;                ///< unit, or zero where the file's was
  std::vector<uint32_t> corner_attributes_;  ///< per kept triangle corner: its t and n indices
  bool uses_attributes_ = false;
  uint32_t material_ = kNoMaterial;  ///< index into usemtls of the faces being read
  bool warned_zero_normal_ = false;
  std::set<std::string> warned_;
  std::vector<Corner> corners_;
  ObjRead out_;
};

// ---- MTL to rayfarm materials ----------------------------------------------------------------

Vec3 to_vec3(const float* v) { return {v[0], v[1], v[2]}; }

/// A reflectance from the MTL: negative is an error, above 1 is clamped with a warning.
Vec3 reflectance(const float* v, const char* key, const Where& at,
                 std::vector<std::string>* warnings) {
  const Vec3 value = to_vec3(v);
  if (min_component(value) < 0.f) at.fail(std::string(key) + " must not be negative");
  if (max_component(value) > 1.f) {
    warnings->push_back(at.message(std::string(key) + " is above 1 and is clamped to [0, 1]"));
  }
  return min(value, Vec3(1.f));
}

/// Scales kd and ks down together so that kd + ks <= 1 in every channel.
void conserve_energy(PhongMaterial* m, const Where& at, std::vector<std::string>* warnings) {
  const float total = max_component(m->kd + m->ks);
  if (total <= 1.f) return;
  m->kd /= total;
  m->ks /= total;
  warnings->push_back(
      at.message("Kd + Ks exceeds 1; both are scaled down by " + std::to_string(total)));
}

/// Maps one MTL material to ours (docs/scene-format.md, "MTL materials").
Material to_material(const MtlMaterial& mtl, const std::string& name, const Where& at,
                     std::vector<std::string>* warnings) {
  Material m;
  m.name = name;
  m.emission = to_vec3(mtl.emission);
  if (min_component(m.emission) < 0.f) at.fail("Ke must not be negative");
  const Vec3 kd = reflectance(mtl.diffuse, "Kd", at, warnings);
  const Vec3 ks = reflectance(mtl.specular, "Ks", at, warnings);
  const int illum = mtl.illum;
  if (illum == 4 || illum == 6 || illum == 7 || (mtl.ior != 1.f && mtl.dissolve < 1.f)) {
    if (!(mtl.ior > 0.f)) at.fail("Ni must be positive for a transparent material");
    const Vec3 tf = reflectance(mtl.transmittance, "Tf", at, warnings);
    m.kind = DielectricMaterial{mtl.ior, is_black(tf) ? Vec3(1.f) : tf};
  } else if (illum == 3 || illum == 5) {
    m.kind = MirrorMaterial{ks};
  } else if (!is_black(ks)) {
    if (mtl.shininess < 0.f) at.fail("Ns must not be negative");
    PhongMaterial phong{kd, ks, mtl.shininess};
    conserve_energy(&phong, at, warnings);
    m.kind = phong;
  } else {
    m.kind = DiffuseMaterial{kd};
  }
  return m;
}

}  // namespace

MeshFile load_obj(const fs::path& scene_dir, const fs::path& relative, bool materials) {
  const std::string display = (scene_dir / relative).string();
  MeshFile result;
  result.files.push_back(relative);
  ObjRead obj =
      ObjReader().read(read_text_file(scene_dir / relative, kMaxObjFileBytes, display), display);
  result.warnings = std::move(obj.warnings);
  if (!materials) {
    obj.mtllibs.clear();
    obj.usemtls.clear();
    obj.faces_without_usemtl = !obj.mesh.materials.empty();
    for (uint32_t& m : obj.mesh.materials) m = kNoMaterial;
  }
  const MtlLibrary library = load_mtllibs(scene_dir, relative, obj.mtllibs);
  result.files.insert(result.files.end(), library.files.begin(), library.files.end());
  result.warnings.insert(result.warnings.end(), library.warnings.begin(), library.warnings.end());

  // Each usemtl names a material of the library, or the default one when no mtllib came before.
  const uint32_t fallback = static_cast<uint32_t>(library.materials.size());
  bool uses_default = obj.faces_without_usemtl;
  std::vector<uint32_t> material_of;
  for (size_t u = 0; u < obj.usemtls.size(); ++u) {
    const UseMtl& use = obj.usemtls[u];
    const auto it = library.index.find(use.name);
    if (it == library.index.end()) {
      use.at.fail("usemtl " + in_quotes(use.name) + ": no material of that name in the MTL files");
    }
    if (!use.after_mtllib) {
      result.warnings.push_back(use.at.message("usemtl " + in_quotes(use.name) +
                                               " comes before any mtllib; its faces get the "
                                               "default material"));
    }
    material_of.push_back(use.after_mtllib ? static_cast<uint32_t>(it->second) : fallback);
    uses_default = uses_default || (!use.after_mtllib && obj.usemtl_has_faces[u]);
  }
  for (uint32_t& m : obj.mesh.materials) m = m == kNoMaterial ? fallback : material_of[m];

  const std::string prefix = relative.generic_string() + ":";
  for (size_t i = 0; i < library.materials.size(); ++i) {
    const auto& mtl = library.materials[i];
    result.materials.push_back(
        to_material(mtl, prefix + mtl.name, library.defined_at[i], &result.warnings));
  }
  if (uses_default) {
    Material fallback_material;
    fallback_material.name = prefix + "default";
    result.materials.push_back(fallback_material);
  }
  if (obj.dropped > 0) {
    result.warnings.push_back(display + ": " + std::to_string(obj.dropped) +
                              " zero-area triangle(s) dropped");
  }
  result.mesh = std::move(obj.mesh);
  result.mesh.origin = relative.generic_string();
  // Only starts before the last triangle begin an object (a trailing "o" names nothing).
  const auto triangles = static_cast<uint32_t>(result.mesh.triangle_count());
  for (size_t k = 0; k < obj.object_starts.size() && obj.object_starts[k] < triangles; ++k)
    result.object_starts.push_back(obj.object_starts[k]);
  if (result.object_starts.size() >= kMaxMeshObjects) result.object_starts.clear();
  if (!result.object_starts.empty()) {
    result.object_names.assign(obj.object_names.begin(),
                               obj.object_names.begin() + result.object_starts.size() + 1);
  }
  return result;
}

std::vector<TriangleMesh> split_objects(TriangleMesh&& mesh, const std::vector<uint32_t>& starts,
                                        const std::vector<std::string>& names) {
  std::vector<TriangleMesh> parts;
  const size_t triangles = mesh.triangle_count();
  if (starts.empty() || starts.size() >= kMaxMeshObjects) {
    parts.push_back(std::move(mesh));
    return parts;
  }
  // Each part keeps the vertices its triangles use, in the order they are first used; `slot`
  // maps a vertex of the whole mesh to its index in the part being built, valid when `owner`
  // names that part.
  std::vector<uint32_t> slot(mesh.positions.size()), owner(mesh.positions.size(), UINT32_MAX);
  for (size_t k = 0; k <= starts.size(); ++k) {
    const size_t first = k == 0 ? 0 : starts[k - 1];
    const size_t last = k == starts.size() ? triangles : starts[k];
    if (first >= last) continue;
    TriangleMesh part;
    const bool named = k < names.size() && !names[k].empty();
    part.origin = mesh.origin + " (object " + (named ? names[k] : std::to_string(k + 1)) + ")";
    part.materials.assign(mesh.materials.begin() + first, mesh.materials.begin() + last);
    part.indices.reserve(3 * (last - first));
    for (size_t i = 3 * first; i < 3 * last; ++i) {
      const uint32_t v = mesh.indices[i];
      if (owner[v] != k) {
        owner[v] = static_cast<uint32_t>(k);
        slot[v] = static_cast<uint32_t>(part.positions.size());
        part.positions.push_back(mesh.positions[v]);
        if (!mesh.normals.empty()) part.normals.push_back(mesh.normals[v]);
        if (!mesh.uvs.empty()) part.uvs.push_back(mesh.uvs[v]);
        if (!mesh.tangents.empty()) part.tangents.push_back(mesh.tangents[v]);
      }
      part.indices.push_back(slot[v]);
    }
    parts.push_back(std::move(part));
  }
  return parts;
}

}  // namespace rayfarm
