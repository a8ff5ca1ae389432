// PLY meshes: the header says what each property of the vertex and face elements is for, the body
// is read record by record (ply_body.h), and the mesh is built as the OBJ reader builds it: the
// same coordinate bounds, normals normalised (zero ones kept as "flat here"), faces
// fan-triangulated and zero-area triangles dropped. Other elements and properties are skipped.
#include "common/scene/ply_loader.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <optional>

#include "common/limits.h"
#include "common/math/wide.h"
#include "common/scene/ply_body.h"
#include "common/scene/text_lines.h"

namespace rayfarm {
namespace fs = std::filesystem;
using ply::Element;
using ply::number_text;
using ply::Property;
using scene_text::in_quotes;
using scene_text::Where;

namespace {

constexpr uint64_t kMaxFaceVertices = 255;  // the most corners of a face read, as for OBJ

/// What a property of the vertex or face element is read for.
enum Role : uint8_t { kSkip, kX, kY, kZ, kNx, kNy, kNz, kU, kV, kCorners };

/// The texture coordinate pairs read, by the names writers use; the first one present is taken.
constexpr const char* kUvNames[][2] = {
    {"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};

/// What each property of an element is for (all kSkip for the elements not read).
struct Layout {
  std::vector<Role> roles;
  bool normals = false, uvs = false;
};

/// The vertex element's properties: x, y, z required and scalar; nx, ny, nz all or none; a
/// texture coordinate pair complete.
Layout vertex_layout(const Element& e, const std::string& file) {
  Layout layout;
  layout.roles.assign(e.properties.size(), kSkip);
  const Where at{file, e.line};
  auto assign = [&](const char* name, Role role) {
    const auto i = e.find(name);
    if (!i) return false;
    const Property& p = e.properties[*i];
    if (p.is_list) {
      Where{file, p.line}.fail("vertex property " + in_quotes(name) +
                               " is a list; expected a single number");
    }
    layout.roles[*i] = role;
    return true;
  };
  for (const auto& [name, role] : {std::pair{"x", kX}, {"y", kY}, {"z", kZ}}) {
    if (!assign(name, role)) {
      at.fail("element \"vertex\" has no property " + in_quotes(name) +
              "; vertices need x, y and z");
    }
  }
  const int normals = int(assign("nx", kNx)) + int(assign("ny", kNy)) + int(assign("nz", kNz));
  if (normals != 0 && normals != 3) {
    at.fail("element \"vertex\" has some of the normal properties nx, ny, nz but not all three");
  }
  layout.normals = normals == 3;
  for (const auto& pair : kUvNames) {
    if (e.find(pair[0]) && e.find(pair[1])) {
      assign(pair[0], kU);
      assign(pair[1], kV);
      layout.uvs = true;
      break;
    }
  }
  if (!layout.uvs) {
    for (const auto& pair : kUvNames) {
      for (int k = 0; k < 2; ++k) {
        if (e.find(pair[k])) {
          at.fail("element \"vertex\" has the texture coordinate " + in_quotes(pair[k]) +
                  " without " + in_quotes(pair[1 - k]));
        }
      }
    }
  }
  return layout;
}

/// The face element's properties: the list of corners is vertex_indices (or vertex_index), of
/// integers.
Layout face_layout(const Element& e, const std::string& file) {
  Layout layout;
  layout.roles.assign(e.properties.size(), kSkip);
  auto i = e.find("vertex_indices");
  if (!i) i = e.find("vertex_index");
  if (!i) {
    Where{file, e.line}.fail(
        "element \"face\" has no property vertex_indices (or vertex_index) listing its corners");
  }
  const Property& p = e.properties[*i];
  if (!p.is_list || !ply::is_integer(p.type)) {
    Where{file, p.line}.fail("face property " + in_quotes(p.name) +
                             " must be a list of integers, e.g. \"property list uchar int " +
                             p.name + "\"");
  }
  layout.roles[*i] = kCorners;
  return layout;
}

/// The fewest bytes a record can have: its scalars, and each list's length (a face's corners at
/// least 3 items).
uint64_t min_record_bytes(const Element& e, const Layout& layout) {
  uint64_t bytes = 0;
  for (size_t i = 0; i < e.properties.size(); ++i) {
    const Property& p = e.properties[i];
    bytes += ply::size_of(p.is_list ? p.count_type : p.type);
    if (layout.roles[i] == kCorners) bytes += 3 * ply::size_of(p.type);
  }
  return bytes;
}

/// Reads the elements in header order into a mesh.
class MeshReader {
 public:
  MeshReader(const ply::Header& header, const std::string& file) : header_(header), file_(file) {
    const Element* vertex = nullptr;
    const Element* face = nullptr;
    for (const Element& e : header.elements) {
      Layout layout;
      if (e.name == "vertex" || e.name == "face") {
        const Element*& seen = e.name == "vertex" ? vertex : face;
        if (seen) Where{file, e.line}.fail("a second element " + in_quotes(e.name));
        seen = &e;
        layout = e.name == "vertex" ? vertex_layout(e, file) : face_layout(e, file);
      } else {
        layout.roles.assign(e.properties.size(), kSkip);
      }
      min_bytes_.push_back(min_record_bytes(e, layout));
      layouts_.push_back(std::move(layout));
    }
    if (vertex) {
      if (vertex->count > UINT32_MAX) {
        Where{file, vertex->line}.fail("element \"vertex\": " + std::to_string(vertex->count) +
                                       " vertices; at most 4294967295 are supported");
      }
      vertex_count_ = vertex->count;
    }
  }

  /// Whether the file has a face (even one whose triangles were all dropped).
  bool any_face() const { return any_face_; }

  template <class Body>
  MeshFile read(Body& body) {
    body.check_counts(header_.elements, min_bytes_);
    for (size_t i = 0; i < header_.elements.size(); ++i) {
      const Element& e = header_.elements[i];
      if (e.properties.empty()) continue;  // records without values take no bytes
      const Layout& layout = layouts_[i];
      if (e.name == "vertex") reserve(layout);
      for (uint64_t r = 0; r < e.count; ++r) record(body, e, layout, r);
    }
    body.finish(&out_.warnings);
    return finish();
  }

 private:
  void reserve(const Layout& layout) {
    // The counts were checked against the file's bytes (lines) before this.
    mesh_.positions.reserve(vertex_count_);
    if (layout.normals) mesh_.normals.reserve(vertex_count_);
    if (layout.uvs) mesh_.uvs.reserve(vertex_count_);
  }

  template <class Body>
  void record(Body& body, const Element& e, const Layout& layout, uint64_t index) {
    body.begin(e, index);
    double v[kCorners] = {};
    for (size_t i = 0; i < e.properties.size(); ++i) {
      const Property& p = e.properties[i];
      const Role role = layout.roles[i];
      if (!p.is_list) {
        if (role == kSkip) {
          body.skip_value(p);
        } else {
          v[role] = body.value(p);
          check_value(body, p, role, v[role]);
        }
      } else if (role == kCorners) {
        corners(body, p);
      } else {
        body.skip_items(p, body.length(p));
      }
    }
    body.end();
    if (e.name == "vertex") vertex(body, layout, v);
  }

  template <class Body>
  static void check_value(const Body& body, const Property& p, Role role, double value) {
    const bool position = role == kX || role == kY || role == kZ;
    if (!std::isfinite(value) || std::abs(value) > kMaxAbsNumber) {
      body.fail("property " + in_quotes(p.name) + " is " + number_text(value) +
                ", not a finite number of magnitude at most 1e30");
    }
    if (position && std::abs(value) > kMaxCoordinate) {
      body.fail("coordinate " + p.name + " = " + number_text(value) +
                " is beyond 1e17, the largest that the renderer handles");
    }
  }

  template <class Body>
  void vertex(const Body& body, const Layout& layout, const double* v) {
    mesh_.positions.push_back(
        {static_cast<float>(v[kX]), static_cast<float>(v[kY]), static_cast<float>(v[kZ])});
    if (layout.uvs) mesh_.uvs.push_back({static_cast<float>(v[kU]), static_cast<float>(v[kV])});
    if (!layout.normals) return;
    const WideVec3 n{v[kNx], v[kNy], v[kNz]};
    const double len = length(n);
    if (!(len > 0.0) && !warned_zero_normal_) {
      warned_zero_normal_ = true;
      out_.warnings.push_back(body.place() +
                              ": the normal has zero length: triangles that use this vertex are "
                              "shaded with their geometric normal");
    }
    mesh_.normals.push_back(len > 0.0
                                ? Vec3(static_cast<float>(n.x / len), static_cast<float>(n.y / len),
                                       static_cast<float>(n.z / len))
                                : Vec3(0.f));
  }

  template <class Body>
  void corners(Body& body, const Property& p) {
    const uint64_t count = body.length(p);
    if (count < 3) body.fail("face with " + std::to_string(count) + " vertices; at least 3 needed");
    if (count > kMaxFaceVertices) {
      body.fail("face with " + std::to_string(count) + " vertices; at most " +
                std::to_string(kMaxFaceVertices) + " are supported");
    }
    any_face_ = true;
    uint32_t corner[kMaxFaceVertices];
    for (uint64_t k = 0; k < count; ++k) {
      const double index = body.item(p);
      if (index < 0 || index >= static_cast<double>(vertex_count_)) {
        body.fail("vertex index " + number_text(index) + " is out of range: the file has " +
                  std::to_string(vertex_count_) + " vertices");
      }
      corner[k] = static_cast<uint32_t>(index);
    }
    // A fan around the first corner keeps the front face of a planar convex polygon.
    for (uint64_t k = 1; k + 1 < count; ++k)
      mesh_.indices.insert(mesh_.indices.end(), {corner[0], corner[k], corner[k + 1]});
  }

  /// Drops the zero-area triangles (the faces may come before the vertices, so only now) and
  /// gives every face the file's default material.
  MeshFile finish() {
    size_t kept = 0, dropped = 0;
    const std::vector<Vec3>& p = mesh_.positions;
    for (size_t t = 0; t + 2 < mesh_.indices.size(); t += 3) {
      const uint32_t a = mesh_.indices[t], b = mesh_.indices[t + 1], c = mesh_.indices[t + 2];
      if (is_zero(edge_cross(p[a], p[b], p[c]))) {
        ++dropped;
        continue;
      }
      mesh_.indices[kept++] = a;
      mesh_.indices[kept++] = b;
      mesh_.indices[kept++] = c;
    }
    mesh_.indices.resize(kept);
    mesh_.indices.shrink_to_fit();
    mesh_.materials.assign(mesh_.triangle_count(), 0);
    if (dropped > 0) {
      out_.warnings.push_back(file_ + ": " + std::to_string(dropped) +
                              " zero-area triangle(s) dropped");
    }
    out_.mesh = std::move(mesh_);
    return std::move(out_);
  }

  const ply::Header& header_;
  const std::string& file_;
  std::vector<Layout> layouts_;
  std::vector<uint64_t> min_bytes_;
  uint64_t vertex_count_ = 0;
  TriangleMesh mesh_;
  MeshFile out_;
  bool any_face_ = false;
  bool warned_zero_normal_ = false;
};

}  // namespace

bool is_ply_file(const fs::path& file) {
  const std::string ext = file.extension().string();
  return ext.size() == 4 && ext[0] == '.' &&
         std::tolower(static_cast<unsigned char>(ext[1])) == 'p' &&
         std::tolower(static_cast<unsigned char>(ext[2])) == 'l' &&
         std::tolower(static_cast<unsigned char>(ext[3])) == 'y';
}

MeshFile load_ply(const fs::path& scene_dir, const fs::path& relative) {
  const std::string display = (scene_dir / relative).string();
  const std::string bytes = read_text_file(scene_dir / relative, kMaxPlyFileBytes, display);
  const ply::Header header = ply::read_header(bytes, display);
  MeshReader reader(header, display);
  MeshFile result;
  if (header.format == ply::Format::kAscii) {
    ply::AsciiBody body(bytes, header, display);
    result = reader.read(body);
  } else {
    ply::BinaryBody body(bytes, header, display);
    result = reader.read(body);
  }
  if (reader.any_face()) {
    // As for an OBJ without MTL files: every face gets the file's default material.
    Material fallback;
    fallback.name = relative.generic_string() + ":default";
    result.materials.push_back(std::move(fallback));
  }
  result.files.push_back(relative);
  result.mesh.origin = relative.generic_string();
  return result;
}

}  // namespace rayfarm
