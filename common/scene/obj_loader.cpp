// OBJ meshes and MTL materials. Every line is checked here first (bytes, numbers, indices against
// the vertices defined so far), so that a bad file is reported as FILE:LINE and only well-formed
// statements reach tinyobjloader; statements we do not use are blanked, keeping line numbers.
#include "common/scene/obj_loader.h"

#include <tiny_obj_loader.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string_view>
#include <system_error>

#include "common/scene/parser.h"

namespace rayfarm {
namespace fs = std::filesystem;

namespace {

constexpr double kMaxAbsValue = 1e30;
/// Largest vertex coordinate: the JSON format's limit for geometry (parser.cpp, kMaxCoordinate).
constexpr double kMaxCoordinate = 1e17;
constexpr size_t kMaxFaceVertices = 255;  // tinyobjloader stores a face's size in one byte
constexpr size_t kMaxNameInMessage = 60;

/// A place in a file, printed "FILE:LINE" (or "FILE" when the line is unknown).
struct Where {
  std::string file;
  size_t line = 0;

  std::string str() const { return line == 0 ? file : file + ":" + std::to_string(line); }
  [[noreturn]] void fail(const std::string& what) const { throw SceneError(str() + ": " + what); }
  std::string message(const std::string& what) const { return str() + ": " + what; }
};

/// Quotes a name taken from a file, shortened so that a message stays readable.
std::string in_quotes(std::string_view name) {
  if (name.size() > kMaxNameInMessage)
    return "\"" + std::string(name.substr(0, kMaxNameInMessage)) + "...\"";
  return "\"" + std::string(name) + "\"";
}

// ---- bytes and lines -------------------------------------------------------------------------

/// Offset of the first byte that does not belong to well-formed UTF-8, or npos.
size_t invalid_utf8_at(std::string_view s) {
  size_t i = 0;
  while (i < s.size()) {
    const auto lead = static_cast<unsigned char>(s[i]);
    if (lead < 0x80) {
      ++i;
      continue;
    }
    size_t length = 0;
    uint32_t code = 0;
    uint32_t smallest = 0;
    if ((lead & 0xE0) == 0xC0) {
      length = 2, code = lead & 0x1Fu, smallest = 0x80;
    } else if ((lead & 0xF0) == 0xE0) {
      length = 3, code = lead & 0x0Fu, smallest = 0x800;
    } else if ((lead & 0xF8) == 0xF0) {
      length = 4, code = lead & 0x07u, smallest = 0x10000;
    } else {
      return i;
    }
    if (i + length > s.size()) return i;
    for (size_t k = 1; k < length; ++k) {
      const auto next = static_cast<unsigned char>(s[i + k]);
      if ((next & 0xC0) != 0x80) return i;
      code = (code << 6) | (next & 0x3Fu);
    }
    if (code < smallest || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return i;
    i += length;
  }
  return std::string_view::npos;
}

/// Rejects bytes that no text line may hold: broken UTF-8, NUL, a carriage return mid-line.
void check_line_bytes(const Where& at, std::string_view line) {
  if (const size_t bad = invalid_utf8_at(line); bad != std::string_view::npos) {
    char hex[8];
    std::snprintf(hex, sizeof hex, "0x%02X", static_cast<unsigned char>(line[bad]));
    at.fail("invalid UTF-8 byte " + std::string(hex) + " at column " + std::to_string(bad + 1));
  }
  if (const size_t nul = line.find('\0'); nul != std::string_view::npos) {
    at.fail("NUL byte at column " + std::to_string(nul + 1));
  }
  if (line.find('\r') != std::string_view::npos) at.fail("carriage return inside a line");
}

/// Calls visit(line_number, line) for every line, without its "\n" or "\r\n", bytes checked.
template <class Visit>
void for_each_line(const std::string& text, const std::string& file, Visit&& visit) {
  size_t start = 0;
  size_t number = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const Where at{file, ++number};
    check_line_bytes(at, line);
    visit(at, line);
    start = end + 1;
  }
}

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

/// The text after the first word, without surrounding blanks ("newmtl my name" -> "my name").
std::string_view rest_after_keyword(std::string_view line, std::string_view keyword) {
  std::string_view rest = line.substr(line.find(keyword) + keyword.size());
  const size_t first = rest.find_first_not_of(" \t");
  if (first == std::string_view::npos) return {};
  rest = rest.substr(first);
  return rest.substr(0, rest.find_last_not_of(" \t") + 1);
}

/// A finite decimal number no larger than 1e30 in magnitude, or nullopt.
std::optional<double> parse_number(std::string_view word) {
  if (!word.empty() && word.front() == '+') word.remove_prefix(1);
  if (word.empty() || word.front() == '+') return std::nullopt;
  double value = 0.0;
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (error != std::errc() || end != word.data() + word.size()) return std::nullopt;
  if (!std::isfinite(value) || std::abs(value) > kMaxAbsValue) return std::nullopt;
  return value;
}

/// Checks that words[1..] are `count` numbers (any count in [min, max]).
void check_numbers(const Where& at, const std::vector<std::string_view>& words, size_t min,
                   size_t max, const std::string& expected) {
  const size_t count = words.size() - 1;
  if (count < min || count > max) {
    at.fail(std::string(words[0]) + ": expected " + expected + ", got " + std::to_string(count) +
            " value(s)");
  }
  for (size_t i = 1; i < words.size(); ++i) {
    if (!parse_number(words[i])) {
      at.fail(std::string(words[0]) + ": " + in_quotes(words[i]) +
              " is not a finite number of magnitude at most 1e30");
    }
  }
}

// ---- OBJ: line checks ------------------------------------------------------------------------

/// What the line check of an OBJ file found.
struct ObjScan {
  std::string text;  ///< the lines tinyobjloader reads: the same count, unused statements blank
  std::vector<std::pair<Where, std::vector<std::string>>> mtllibs;  ///< file names per line
  std::vector<std::pair<Where, std::string>> usemtls;               ///< material name per line
  std::vector<std::string> warnings;
};

/// Checks an OBJ file line by line, counting vertices so that every face index can be checked
/// where it is written (relative indices count back from the vertices defined so far).
class ObjScanner {
 public:
  ObjScan scan(const std::string& text, const std::string& file) {
    for_each_line(text, file, [this](const Where& at, std::string_view line) {
      statement(at, line);
      out_.text += '\n';
    });
    return std::move(out_);
  }

 private:
  void statement(const Where& at, std::string_view line) {
    const std::vector<std::string_view> words = split_words(line);
    if (words.empty() || words[0].front() == '#') return;
    const std::string_view keyword = words[0];
    if (keyword == "v") {
      check_numbers(at, words, 3, 6, "3 coordinates (x y z), optionally w or r g b");
      if (words.size() == 6) at.fail("v: expected 3, 4 or 6 values, got 5");
      for (size_t i = 1; i <= 3; ++i) {
        if (std::abs(*parse_number(words[i])) > kMaxCoordinate) {
          at.fail("v: coordinate " + in_quotes(words[i]) +
                  " is beyond 1e17, the largest that the renderer handles");
        }
      }
      ++vertices_;
    } else if (keyword == "vt") {
      check_numbers(at, words, 1, 3, "1 to 3 texture coordinates");
      ++texcoords_;
    } else if (keyword == "vn") {
      check_numbers(at, words, 3, 3, "3 normal components");
      if (*parse_number(words[1]) == 0.0 && *parse_number(words[2]) == 0.0 &&
          *parse_number(words[3]) == 0.0 && !warned_zero_normal_) {
        warned_zero_normal_ = true;
        out_.warnings.push_back(at.message(
            "vn has zero length (normals are not used: faces are shaded with their geometric "
            "normal)"));
      }
      ++normals_;
    } else if (keyword == "f") {
      face(at, words);
    } else if (keyword == "usemtl") {
      if (words.size() < 2) at.fail("usemtl without a material name");
      out_.usemtls.emplace_back(at, std::string(words[1]));
    } else if (keyword == "mtllib") {
      mtllib(at, line);
      return;
    } else if (keyword != "o" && keyword != "g" && keyword != "s") {
      ignore(at, keyword);
      return;
    }
    out_.text += line;
  }

  void face(const Where& at, const std::vector<std::string_view>& words) {
    const size_t corners = words.size() - 1;
    if (corners < 3)
      at.fail("face with " + std::to_string(corners) + " vertices; at least 3 needed");
    if (corners > kMaxFaceVertices) {
      at.fail("face with " + std::to_string(corners) + " vertices; at most " +
              std::to_string(kMaxFaceVertices) + " are supported");
    }
    for (size_t i = 1; i < words.size(); ++i) corner(at, words[i]);
  }

  /// One "v", "v/t", "v//n" or "v/t/n" reference.
  void corner(const Where& at, std::string_view word) {
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
    index(at, parts[0], vertices_, "vertex");
    if (parts.size() >= 2 && !parts[1].empty())
      index(at, parts[1], texcoords_, "texture coordinate");
    if (parts.size() == 3) index(at, parts[2], normals_, "normal");
  }

  static void index(const Where& at, std::string_view word, size_t defined, const char* what) {
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
  }

  /// mtllib lines become one "mtllib @" line whose materials are those we load and check.
  void mtllib(const Where& at, std::string_view line) {
    std::vector<std::string> names;
    std::string name;
    const std::string_view rest = rest_after_keyword(line, "mtllib");
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
    if (out_.mtllibs.empty()) out_.text += "mtllib @";
    out_.mtllibs.emplace_back(at, std::move(names));
  }

  void ignore(const Where& at, std::string_view keyword) {
    if (warned_.insert(std::string(keyword)).second) {
      out_.warnings.push_back(
          at.message("statement " + in_quotes(keyword) + " is not supported and is ignored"));
    }
  }

  size_t vertices_ = 0;
  size_t texcoords_ = 0;
  size_t normals_ = 0;
  bool warned_zero_normal_ = false;
  std::set<std::string> warned_;
  ObjScan out_;
};

// ---- MTL -------------------------------------------------------------------------------------

/// The materials of all MTL files an OBJ names, in file order, first definition of a name kept.
struct MtlLibrary {
  std::vector<tinyobj::material_t> materials;
  std::vector<Where> defined_at;  ///< the newmtl line of each material
  std::map<std::string, int> index;
  std::vector<fs::path> files;
  std::vector<std::string> warnings;
};

/// Checks an MTL file line by line and returns the text tinyobjloader reads: the same lines,
/// "newmtl" names trimmed, statements we do not use blank. `names` gets each newmtl line.
std::string check_mtl(const std::string& text, const std::string& file,
                      std::vector<std::pair<Where, std::string>>* names,
                      std::vector<std::string>* warnings) {
  std::string out;
  std::set<std::string> warned;
  for_each_line(text, file, [&](const Where& at, std::string_view line) {
    const std::vector<std::string_view> words = split_words(line);
    const std::string_view keyword = words.empty() ? std::string_view{} : words[0];
    if (keyword == "newmtl") {
      const std::string_view name = rest_after_keyword(line, "newmtl");
      if (name.empty()) at.fail("newmtl without a material name");
      names->emplace_back(at, std::string(name));
      out += "newmtl " + std::string(name);
    } else if (keyword == "Kd" || keyword == "Ks" || keyword == "Ke" || keyword == "Tf" ||
               keyword == "Kt") {
      check_numbers(at, words, 3, 3, "3 numbers (r g b)");
      out += line;
    } else if (keyword == "Ni" || keyword == "Ns" || keyword == "d" || keyword == "Tr") {
      check_numbers(at, words, 1, 1, "1 number");
      out += line;
    } else if (keyword == "illum") {
      int model = -1;
      bool ok = words.size() == 2;
      if (ok) {
        const char* end = words[1].data() + words[1].size();
        ok = std::from_chars(words[1].data(), end, model).ptr == end && model >= 0 && model <= 10;
      }
      if (!ok) at.fail("illum: expected an integer from 0 to 10");
      out += line;
    } else if (!keyword.empty() && keyword.front() != '#' && keyword != "Ka" &&
               warned.insert(std::string(keyword)).second) {
      warnings->push_back(
          at.message("statement " + in_quotes(keyword) + " is not supported and is ignored"));
    }
    out += '\n';
  });
  return out;
}

/// Loads one MTL file into the library; a name defined before keeps its first definition.
void load_mtl(const fs::path& scene_dir, const fs::path& relative, MtlLibrary* library) {
  const std::string display = (scene_dir / relative).string();
  const std::string text = read_text_file(scene_dir / relative, kMaxMtlFileBytes, display);
  std::vector<std::pair<Where, std::string>> names;
  std::istringstream checked(check_mtl(text, display, &names, &library->warnings));

  std::vector<tinyobj::material_t> materials;
  std::map<std::string, int> index;
  std::string warn;
  std::string err;
  tinyobj::LoadMtl(&index, &materials, &checked, &warn, &err);
  if (!err.empty()) throw SceneError(display + ": " + err.substr(0, err.find('\n')));
  if (materials.size() != names.size()) throw SceneError(display + ": cannot read the materials");
  library->files.push_back(relative);
  for (size_t i = 0; i < materials.size(); ++i) {
    const auto [where, name] = names[i];
    if (library->index.count(name) != 0) {
      library->warnings.push_back(where.message("material " + in_quotes(name) +
                                                " is defined again; the first one is used"));
      continue;
    }
    library->index[name] = static_cast<int>(library->materials.size());
    library->materials.push_back(materials[i]);
    library->defined_at.push_back(where);
  }
}

/// Loads every file named by the OBJ's mtllib lines; paths are relative to the OBJ's folder.
MtlLibrary load_mtllibs(const fs::path& scene_dir, const fs::path& obj, const ObjScan& scan) {
  MtlLibrary library;
  std::set<fs::path> loaded;
  for (const auto& [where, names] : scan.mtllibs) {
    for (const std::string& name : names) {
      std::string why;
      const auto relative = resolve_scene_path(obj.parent_path(), name, &why);
      if (!relative) where.fail("mtllib " + in_quotes(name) + ": " + why);
      if (!fs::exists(scene_dir / *relative)) {
        where.fail("mtllib " + in_quotes(name) + ": file not found (looked for " +
                   (scene_dir / *relative).string() + ")");
      }
      if (loaded.insert(*relative).second) load_mtl(scene_dir, *relative, &library);
    }
  }
  for (const auto& [where, name] : scan.usemtls) {
    if (library.index.count(name) == 0) {
      where.fail("usemtl " + in_quotes(name) + ": no material of that name in the MTL files");
    }
  }
  return library;
}

/// Hands the library we loaded and checked to tinyobjloader when it reads "mtllib @".
class LibraryReader final : public tinyobj::MaterialReader {
 public:
  explicit LibraryReader(const MtlLibrary& library) : library_(library) {}
  bool operator()(const std::string& /*name*/, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* index, std::string* /*warn*/,
                  std::string* /*err*/) override {
    *materials = library_.materials;
    *index = library_.index;
    return true;
  }

 private:
  const MtlLibrary& library_;
};

// ---- MTL to rayfarm materials ----------------------------------------------------------------

Vec3 to_vec3(const tinyobj::real_t* v) { return {v[0], v[1], v[2]}; }

/// A reflectance from the MTL: negative is an error, above 1 is clamped with a warning.
Vec3 reflectance(const tinyobj::real_t* v, const char* key, const Where& at,
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
Material to_material(const tinyobj::material_t& mtl, const std::string& name, const Where& at,
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

// ---- the mesh --------------------------------------------------------------------------------

bool zero_area(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double e1[3] = {double(b.x) - a.x, double(b.y) - a.y, double(b.z) - a.z};
  const double e2[3] = {double(c.x) - a.x, double(c.y) - a.y, double(c.z) - a.z};
  const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                       e1[0] * e2[1] - e1[1] * e2[0]};
  return n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0;
}

/// Fan-triangulates tinyobjloader's faces, checking every index it hands back.
class MeshBuilder {
 public:
  MeshBuilder(const tinyobj::attrib_t& attrib, size_t materials, const std::string& file)
      : materials_(materials), file_(file) {
    const std::vector<tinyobj::real_t>& v = attrib.vertices;
    if (v.size() % 3 != 0 || v.size() / 3 >= UINT32_MAX) fail("unexpected vertex data");
    mesh_.positions.reserve(v.size() / 3);
    for (size_t i = 0; i + 2 < v.size(); i += 3) {
      const Vec3 p{v[i], v[i + 1], v[i + 2]};
      if (!is_finite(p)) fail("vertex " + std::to_string(i / 3 + 1) + " is not finite");
      mesh_.positions.push_back(p);
    }
  }

  void add(const tinyobj::mesh_t& shape) {
    size_t first = 0;
    for (size_t f = 0; f < shape.num_face_vertices.size(); ++f) {
      const size_t corners = shape.num_face_vertices[f];
      if (corners < 3 || first + corners > shape.indices.size()) fail("unexpected face data");
      const int id = f < shape.material_ids.size() ? shape.material_ids[f] : -1;
      if (id < -1 || id >= static_cast<int>(materials_)) fail("unexpected material index");
      const uint32_t material = id < 0 ? default_material() : static_cast<uint32_t>(id);
      for (size_t k = 1; k + 1 < corners; ++k) {
        triangle(shape.indices[first], shape.indices[first + k], shape.indices[first + k + 1],
                 material);
      }
      first += corners;
    }
  }

  bool uses_default_material() const { return uses_default_; }
  size_t dropped() const { return dropped_; }
  TriangleMesh take() { return std::move(mesh_); }

 private:
  void triangle(const tinyobj::index_t& a, const tinyobj::index_t& b, const tinyobj::index_t& c,
                uint32_t material) {
    const uint32_t ia = vertex(a), ib = vertex(b), ic = vertex(c);
    if (zero_area(mesh_.positions[ia], mesh_.positions[ib], mesh_.positions[ic])) {
      ++dropped_;
      return;
    }
    mesh_.indices.insert(mesh_.indices.end(), {ia, ib, ic});
    mesh_.materials.push_back(material);
  }

  uint32_t vertex(const tinyobj::index_t& index) const {
    const int i = index.vertex_index;
    if (i < 0 || static_cast<size_t>(i) >= mesh_.positions.size())
      fail("vertex index out of range");
    return static_cast<uint32_t>(i);
  }

  uint32_t default_material() {
    uses_default_ = true;
    return static_cast<uint32_t>(materials_);
  }

  [[noreturn]] void fail(const std::string& what) const { throw SceneError(file_ + ": " + what); }

  size_t materials_;
  const std::string& file_;
  TriangleMesh mesh_;
  bool uses_default_ = false;
  size_t dropped_ = 0;
};

/// Runs tinyobjloader on the checked text; its errors and warnings name the file.
void run_tinyobj(const std::string& text, const MtlLibrary& library, const std::string& display,
                 tinyobj::attrib_t* attrib, std::vector<tinyobj::shape_t>* shapes,
                 std::vector<std::string>* warnings) {
  std::istringstream in(text);
  LibraryReader reader(library);
  std::vector<tinyobj::material_t> materials;
  std::string warn;
  std::string err;
  const bool ok = tinyobj::LoadObj(attrib, shapes, &materials, &warn, &err, &in, &reader,
                                   /*triangulate=*/false, /*default_vcols_fallback=*/false);
  if (!ok || !err.empty()) throw SceneError(display + ": " + err.substr(0, err.find('\n')));
  std::istringstream lines(warn);
  for (std::string line; std::getline(lines, line);) {
    if (!line.empty()) warnings->push_back(display + ": " + line);
  }
}

}  // namespace

std::string read_text_file(const fs::path& file, std::uintmax_t max_bytes,
                           const std::string& display) {
  std::error_code error;
  const fs::file_status status = fs::status(file, error);
  if (error || !fs::exists(status)) throw SceneError(display + ": file not found");
  if (!fs::is_regular_file(status)) throw SceneError(display + ": not a regular file");
  const std::uintmax_t size = fs::file_size(file, error);
  if (error) throw SceneError(display + ": cannot read the file size: " + error.message());
  if (size > max_bytes) {
    throw SceneError(display + ": the file has " + std::to_string(size) +
                     " bytes, more than the limit of " + std::to_string(max_bytes));
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SceneError(display + ": cannot open the file");
  std::string text(static_cast<size_t>(size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    throw SceneError(display + ": cannot read the file");
  }
  return text;
}

std::optional<fs::path> resolve_scene_path(const fs::path& base_dir, const std::string& reference,
                                           std::string* why) {
  if (reference.empty()) {
    *why = "the path is empty";
    return std::nullopt;
  }
  if (reference.find('\0') != std::string::npos) {
    *why = "the path contains a NUL character";
    return std::nullopt;
  }
  const fs::path path(reference);
  if (path.has_root_path()) {
    *why = "absolute paths are not allowed; give a path relative to the scene's folder";
    return std::nullopt;
  }
  const fs::path joined = (base_dir / path).lexically_normal();
  if (joined.empty() || *joined.begin() == "..") {
    *why = "the path leaves the scene's folder";
    return std::nullopt;
  }
  if (!joined.has_filename() || joined == ".") {
    *why = "the path names a folder, not a file";
    return std::nullopt;
  }
  return joined;
}

ObjMesh load_obj(const fs::path& scene_dir, const fs::path& relative) {
  const std::string display = (scene_dir / relative).string();
  ObjMesh result;
  result.files.push_back(relative);
  ObjScan scan =
      ObjScanner().scan(read_text_file(scene_dir / relative, kMaxObjFileBytes, display), display);
  result.warnings = std::move(scan.warnings);
  MtlLibrary library = load_mtllibs(scene_dir, relative, scan);
  result.files.insert(result.files.end(), library.files.begin(), library.files.end());
  result.warnings.insert(result.warnings.end(), library.warnings.begin(), library.warnings.end());

  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  run_tinyobj(scan.text, library, display, &attrib, &shapes, &result.warnings);
  scan.text = std::string();

  const std::string prefix = relative.generic_string() + ":";
  for (size_t i = 0; i < library.materials.size(); ++i) {
    const auto& mtl = library.materials[i];
    result.materials.push_back(
        to_material(mtl, prefix + mtl.name, library.defined_at[i], &result.warnings));
  }
  MeshBuilder builder(attrib, library.materials.size(), display);
  for (const tinyobj::shape_t& shape : shapes) builder.add(shape.mesh);
  if (builder.uses_default_material()) {
    Material fallback;
    fallback.name = prefix + "default";
    result.materials.push_back(fallback);
  }
  if (builder.dropped() > 0) {
    result.warnings.push_back(display + ": " + std::to_string(builder.dropped()) +
                              " zero-area triangle(s) dropped");
  }
  result.mesh = builder.take();
  result.mesh.origin = relative.generic_string();
  return result;
}

}  // namespace rayfarm
