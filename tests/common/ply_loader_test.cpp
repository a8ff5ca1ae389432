// PLY meshes in scenes: the three formats read the same mesh, normals and texture coordinates
// come through, polygons are fan-triangulated, what the reader does not use is skipped by its
// true size, and every kind of malformed or lying file is rejected with an error that names the
// file and the place (header line, or element, record and line or byte).
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "common/bundle/bundle.h"
#include "common/scene/parser.h"
#include "common/scene/ply_loader.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

enum class Format { kAscii, kLittle, kBig };

/// One element of a PLY file to write: its property declarations as the header writes them
/// ("float x", "list uchar int vertex_indices") and its records, each the values of its
/// properties in order (a list: its length, then its items).
struct Elem {
  std::string name;
  std::vector<std::string> props;
  std::vector<std::vector<double>> rows;
  uint64_t declared = UINT64_MAX;  ///< the count written in the header, when not rows.size()
};

void put(std::string* out, const std::string& type, double v, Format f) {
  unsigned char raw[8];
  size_t n = 0;
  auto store = [&](auto value) {
    n = sizeof(value);
    std::memcpy(raw, &value, n);
  };
  if (type == "char" || type == "int8")
    store(static_cast<int8_t>(v));
  else if (type == "uchar" || type == "uint8")
    store(static_cast<uint8_t>(v));
  else if (type == "short" || type == "int16")
    store(static_cast<int16_t>(v));
  else if (type == "ushort" || type == "uint16")
    store(static_cast<uint16_t>(v));
  else if (type == "int" || type == "int32")
    store(static_cast<int32_t>(v));
  else if (type == "uint" || type == "uint32")
    store(static_cast<uint32_t>(v));
  else if (type == "float" || type == "float32")
    store(static_cast<float>(v));
  else
    store(v);
  const bool big = f == Format::kBig;
  if (big != (std::endian::native == std::endian::big)) std::reverse(raw, raw + n);
  out->append(reinterpret_cast<const char*>(raw), n);
}

std::string number(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

/// The PLY file of `elems` in format `f`, with `extra` header lines after the format line.
std::string write_ply(Format f, const std::vector<Elem>& elems, const std::string& extra = "") {
  std::string out = "ply\nformat ";
  out += f == Format::kAscii    ? "ascii"
         : f == Format::kLittle ? "binary_little_endian"
                                : "binary_big_endian";
  out += " 1.0\ncomment written by the PLY reader's tests\n" + extra;
  for (const Elem& e : elems) {
    const uint64_t count = e.declared == UINT64_MAX ? e.rows.size() : e.declared;
    out += "element " + e.name + " " + std::to_string(count) + "\n";
    for (const std::string& p : e.props) out += "property " + p + "\n";
  }
  out += "end_header\n";
  for (const Elem& e : elems) {
    for (const std::vector<double>& row : e.rows) {
      size_t v = 0;
      std::string line;
      for (const std::string& decl : e.props) {
        std::istringstream words(decl);
        std::string first, count_type, item_type;
        words >> first;
        const bool list = first == "list";
        if (list) words >> count_type >> item_type;
        const std::vector<std::string> types =
            list ? std::vector<std::string>{count_type, item_type} : std::vector{first};
        // A list writes as many items as its length says, or as the row has left when that is
        // fewer (a lying length), none when it is negative.
        const size_t left = row.size() - v - 1;
        const size_t items = row.at(v) <= 0 ? 0 : std::min(left, static_cast<size_t>(row.at(v)));
        const size_t values = list ? 1 + items : 1;
        for (size_t k = 0; k < values; ++k, ++v) {
          if (f != Format::kAscii) {
            put(&out, types[k == 0 ? 0 : types.size() - 1], row.at(v), f);
            continue;
          }
          if (!line.empty()) line += ' ';
          line += number(row.at(v));
        }
      }
      if (f == Format::kAscii) out += line + "\n";
    }
  }
  return out;
}

const std::vector<std::string> kVertexProps = {
    "float x",  "float y",  "float z",    "float nx",
    "float ny", "float nz", "uchar red",  "list uchar float extra",
    "float u",  "float v",  "uchar green"};
const std::vector<std::string> kFaceProps = {"list uchar int vertex_indices", "uchar flags"};

/// A square (a quad) and a triangle below it, with unnormalised normals, texture coordinates,
/// vertex colours, a list the reader skips, and two elements it skips.
std::vector<Elem> sample_mesh() {
  Elem vertex{"vertex", kVertexProps, {}};
  const double xyz[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, -1, 0}};
  for (int i = 0; i < 5; ++i) {
    const double extra = i % 3;  // 0, 1 or 2 items
    std::vector<double> row{xyz[i][0], xyz[i][1], xyz[i][2], 0, 0, 2.0 + i, 200, extra};
    for (int k = 0; k < extra; ++k) row.push_back(0.25 * k);
    row.insert(row.end(), {xyz[i][0], xyz[i][1] * 0.5, 17});
    vertex.rows.push_back(row);
  }
  Elem face{"face", kFaceProps, {{4, 0, 1, 2, 3, 1}, {3, 0, 4, 1, 0}}};
  Elem edge{"edge", {"int vertex1", "int vertex2", "uchar red"}, {{0, 1, 255}, {1, 2, 0}}};
  Elem material{"material",
                {"list ushort double coefficients", "float shininess"},
                {{3, 0.1, 0.2, 0.3, 12}, {0, 5}}};
  Elem marker{"marker", {}, {}, 1000000000000ull};  // no properties: no bytes, nothing to read
  return {vertex, edge, face, material, marker};
}

std::string scene_json(const std::string& mesh_keys) {
  return R"({"camera": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_y": 40},
  "film": {"width": 8, "height": 8},
  "materials": {"red": {"type": "diffuse", "albedo": [0.5, 0.1, 0.1]}},
  "lights": [{"type": "point", "position": [0, 0, -4], "intensity": [1, 1, 1]}],
  "shapes": [{"type": "mesh", )" +
         mesh_keys + "}]}";
}

/// Loads a scene whose one mesh is `ply`, written to `name`.
Scene load_ply_scene(const TempDir& dir, const std::string& ply, const std::string& name = "m.ply",
                     const std::string& more_keys = "") {
  dir.write(name, ply);
  return load_scene(dir.write("scene.json", scene_json("\"file\": \"" + name + "\"" + more_keys)));
}

/// Expects loading a scene with `ply` as its mesh to fail with a message holding every part.
void expect_ply_error(const std::string& ply, std::initializer_list<std::string> parts) {
  TempDir dir;
  try {
    load_ply_scene(dir, ply);
    ADD_FAILURE() << "expected a SceneError for:\n" << ply.substr(0, 400);
  } catch (const SceneError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find((dir.path() / "m.ply").string()), std::string::npos) << message;
    for (const std::string& part : parts)
      EXPECT_NE(message.find(part), std::string::npos) << "\"" << part << "\" not in: " << message;
  }
}

TEST(PlyMesh, TheThreeFormatsGiveTheSameMesh) {
  TempDir dir;
  std::vector<TriangleMesh> meshes;
  for (Format f : {Format::kAscii, Format::kLittle, Format::kBig}) {
    const Scene scene = load_ply_scene(dir, write_ply(f, sample_mesh()));
    EXPECT_TRUE(scene.warnings.empty()) << scene.warnings.at(0);
    ASSERT_EQ(scene.meshes.size(), 1u);
    meshes.push_back(scene.meshes[0]);
  }
  const TriangleMesh& m = meshes[0];
  ASSERT_EQ(m.positions.size(), 5u);
  EXPECT_EQ(m.positions[2], Vec3(1, 1, 0));
  EXPECT_EQ(m.positions[4], Vec3(0.5f, -1, 0));
  // The quad becomes the fan (0 1 2) (0 2 3); the triangle follows.
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 0, 4, 1}));
  ASSERT_EQ(m.normals.size(), 5u);
  for (const Vec3& n : m.normals) EXPECT_EQ(n, Vec3(0, 0, 1));
  ASSERT_EQ(m.uvs.size(), 5u);
  EXPECT_EQ(m.uvs[2].x, 1.f);
  EXPECT_EQ(m.uvs[2].y, 0.5f);
  EXPECT_EQ(m.uvs[4].y, -0.5f);
  EXPECT_EQ(m.origin, "m.ply");
  for (size_t i = 1; i < meshes.size(); ++i) {
    EXPECT_EQ(meshes[i].positions, m.positions);
    EXPECT_EQ(meshes[i].normals, m.normals);
    EXPECT_EQ(meshes[i].indices, m.indices);
    EXPECT_EQ(meshes[i].materials, m.materials);
    ASSERT_EQ(meshes[i].uvs.size(), m.uvs.size());
    for (size_t k = 0; k < m.uvs.size(); ++k) {
      EXPECT_EQ(meshes[i].uvs[k].x, m.uvs[k].x);
      EXPECT_EQ(meshes[i].uvs[k].y, m.uvs[k].y);
    }
  }
}

TEST(PlyMesh, MaterialsFollowTheObjRules) {
  TempDir dir;
  const std::string ply = write_ply(Format::kLittle, sample_mesh());
  // Without a material every face gets "<file>:default", a diffuse of albedo 0.8.
  Scene scene = load_ply_scene(dir, ply, "sub/m.ply");
  ASSERT_EQ(scene.meshes.size(), 1u);
  const Material& fallback = scene.materials.at(scene.meshes[0].materials.at(0));
  EXPECT_EQ(fallback.name, "sub/m.ply:default");
  ASSERT_TRUE(std::holds_alternative<DiffuseMaterial>(fallback.kind));
  EXPECT_EQ(scene.referenced, std::vector<fs::path>{"sub/m.ply"});
  // The shape's material replaces it, and no default material is added.
  scene = load_ply_scene(dir, ply, "m.ply", R"(, "material": "red")");
  EXPECT_EQ(scene.materials.size(), 1u);
  for (uint32_t m : scene.meshes[0].materials) EXPECT_EQ(scene.materials.at(m).name, "red");
  // The transform moves the points and turns the normals.
  scene = load_ply_scene(dir, ply, "m.ply",
                         R"(, "transform": {"rotate": {"axis": [0, 1, 0], "angle": 90}})");
  EXPECT_NEAR(scene.meshes[0].positions[1].z, -1.f, 1e-6f);
  EXPECT_NEAR(scene.meshes[0].normals[0].x, 1.f, 1e-6f);
}

TEST(PlyMesh, ExtensionIsCaseInsensitiveAndOthersStayObj) {
  EXPECT_TRUE(is_ply_file("a/b.ply"));
  EXPECT_TRUE(is_ply_file("B.PLY"));
  EXPECT_TRUE(is_ply_file("c.Ply"));
  EXPECT_FALSE(is_ply_file("c.obj"));
  EXPECT_FALSE(is_ply_file("ply"));
  EXPECT_FALSE(is_ply_file("c.plyx"));
  TempDir dir;
  const Scene scene = load_ply_scene(dir, write_ply(Format::kBig, sample_mesh()), "M.PLY");
  EXPECT_EQ(scene.meshes.at(0).triangle_count(), 3u);
}

TEST(PlyMesh, NamesOfTextureCoordinatesAndCorners) {
  TempDir dir;
  const std::vector<std::vector<double>> rows = {
      {0, 0, 0, 0.1, 0.2}, {1, 0, 0, 0.3, 0.4}, {0, 1, 0, 0.5, 0.6}};
  for (const auto& [u, v] :
       {std::pair{"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}}) {
    const Elem vertex{
        "vertex",
        {"float x", "float y", "float z", std::string("double ") + u, std::string("double ") + v},
        rows};
    const Elem face{"face", {"list int uint vertex_index"}, {{3, 0, 1, 2}}};
    const Scene scene = load_ply_scene(dir, write_ply(Format::kAscii, {vertex, face}));
    const TriangleMesh& m = scene.meshes.at(0);
    ASSERT_EQ(m.uvs.size(), 3u) << u;
    EXPECT_EQ(m.uvs[2].x, 0.5f);
    EXPECT_EQ(m.uvs[2].y, 0.6f);
    EXPECT_TRUE(m.normals.empty());
  }
}

TEST(PlyMesh, IntegerCoordinatesPentagonsAndFacesBeforeVertices) {
  TempDir dir;
  const Elem face{"face", {"list uchar ushort vertex_indices"}, {{5, 0, 1, 2, 3, 4}}};
  const Elem vertex{"vertex",
                    {"short x", "short y", "char z"},
                    {{0, 0, -1}, {2, 0, -1}, {3, 2, -1}, {1, 3, -1}, {-1, 2, -1}}};
  for (Format f : {Format::kAscii, Format::kBig}) {
    const Scene scene = load_ply_scene(dir, write_ply(f, {face, vertex}));
    const TriangleMesh& m = scene.meshes.at(0);
    EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 0, 3, 4}));
    EXPECT_EQ(m.positions[4], Vec3(-1, 2, -1));
  }
}

TEST(PlyMesh, TolerableProblemsAreWarnings) {
  TempDir dir;
  // A zero normal (flat there), a zero-area triangle (dropped), and bytes after the last element.
  const Elem vertex{
      "vertex",
      {"float x", "float y", "float z", "float nx", "float ny", "float nz"},
      {{0, 0, 0, 0, 0, 0}, {1, 0, 0, 0, 0, 1}, {0, 1, 0, 0, 0, 1}, {2, 0, 0, 0, 0, 1}}};
  const Elem face{"face", {"list uchar int vertex_indices"}, {{3, 0, 1, 2}, {3, 0, 1, 3}}};
  Scene scene = load_ply_scene(dir, write_ply(Format::kLittle, {vertex, face}) + "junk");
  ASSERT_EQ(scene.warnings.size(), 3u);
  EXPECT_NE(scene.warnings[0].find("m.ply: vertex 0 (byte "), std::string::npos);
  EXPECT_NE(scene.warnings[0].find("zero length"), std::string::npos);
  EXPECT_NE(scene.warnings[1].find("4 byte(s) after the last element"), std::string::npos);
  EXPECT_NE(scene.warnings[2].find("1 zero-area triangle(s) dropped"), std::string::npos);
  EXPECT_EQ(scene.meshes.at(0).triangle_count(), 1u);
  EXPECT_EQ(scene.meshes[0].normals[0], Vec3(0.f));
  // ASCII: lines after the last element, named by the first one's number.
  scene = load_ply_scene(dir, write_ply(Format::kAscii, {vertex, face}) + "\n9 9 9\n1\n");
  EXPECT_NE(scene.warnings.at(1).find("m.ply:21: 2 line(s) after the last element"),
            std::string::npos)
      << scene.warnings[1];
  // Only vertices: a point cloud has no triangles to render.
  scene = load_ply_scene(dir, write_ply(Format::kAscii, {vertex}));
  EXPECT_TRUE(scene.meshes.empty());
  EXPECT_TRUE(scene.materials.size() == 1u);  // the scene's own "red", no default
}

const std::string kVertexHead =
    "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
const std::string kTriangle =
    kVertexHead + "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
const std::string kAsciiTriangle =
    "ply\nformat ascii 1.0\n" + kTriangle + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

TEST(PlyErrors, HeaderProblemsNameTheLine) {
  expect_ply_error("", {"the file is empty"});
  expect_ply_error("solid x\n", {"m.ply:1: not a PLY file"});
  expect_ply_error("ply\n" + kTriangle, {"m.ply:2: element before any format line"});
  expect_ply_error("ply\ncomment no format\nend_header\n",
                   {"m.ply:3: end_header before any format"});
  expect_ply_error("ply\nformat binary_middle_endian 1.0\n" + kTriangle,
                   {"m.ply:2: unknown format \"binary_middle_endian\""});
  expect_ply_error("ply\nformat ascii 2.0\n" + kTriangle, {"m.ply:2: format version \"2.0\""});
  expect_ply_error("ply\nformat ascii 1.0\nformat ascii 1.0\n", {"m.ply:3: a second format line"});
  expect_ply_error("ply\nformat ascii 1.0\nproperty float x\n",
                   {"m.ply:3: property before any element"});
  expect_ply_error("ply\nformat ascii 1.0\nelement vertex -3\n",
                   {"m.ply:3: element \"vertex\": count \"-3\" is not a non-negative integer"});
  expect_ply_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\n",
                   {"m.ply:4: unknown property type \"float128\""});
  expect_ply_error(
      "ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\n",
      {"m.ply:4: property list \"vertex_indices\": its length type \"float\""});
  expect_ply_error("ply\nformat ascii 1.0\nelement v 1\nproperty float x\nproperty int x\n",
                   {"m.ply:5: element \"v\" has a second property \"x\""});
  expect_ply_error("ply\nformat ascii 1.0\nelement v 1\nproperty float x\n",
                   {"the header has no end_header line"});
  expect_ply_error("ply\nformat ascii 1.0\nmaterial 3\n", {"m.ply:3: unknown header line"});
  {
    // Hundreds of properties: bounded, so that a long header costs no quadratic search.
    std::string many = "ply\nformat ascii 1.0\nelement v 1\n";
    for (int i = 0; i < 257; ++i) many += "property float p" + std::to_string(i) + "\n";
    expect_ply_error(many + "end_header\n", {"m.ply:260: element \"v\" has more than 256"});
  }
  expect_ply_error("ply\nformat ascii 1.0\ncomment \xff\n", {"m.ply:3: invalid UTF-8"});
}

TEST(PlyErrors, ElementsTheMeshNeeds) {
  const std::string head = "ply\nformat ascii 1.0\n";
  expect_ply_error(head + "element vertex 1\nproperty float x\nproperty float z\nend_header\n0 0\n",
                   {"m.ply:3: element \"vertex\" has no property \"y\""});
  expect_ply_error(head +
                       "element vertex 1\nproperty float x\nproperty float y\n"
                       "property list uchar float z\nend_header\n",
                   {"m.ply:6: vertex property \"z\" is a list"});
  expect_ply_error(head + kVertexHead + "property float nx\nproperty float nz\nend_header\n",
                   {"m.ply:3: ", "some of the normal properties nx, ny, nz"});
  expect_ply_error(head + kVertexHead + "property float u\nend_header\n",
                   {"m.ply:3: ", "texture coordinate \"u\" without \"v\""});
  expect_ply_error(head + "element face 1\nproperty int vertex_indices\nend_header\n3\n",
                   {"m.ply:4: face property \"vertex_indices\" must be a list of integers"});
  expect_ply_error(head + "element face 1\nproperty list uchar float vertex_indices\nend_header\n",
                   {"m.ply:4: face property", "list of integers"});
  expect_ply_error(head + "element face 1\nproperty list uchar int corners\nend_header\n",
                   {"m.ply:3: element \"face\" has no property vertex_indices"});
  expect_ply_error(head +
                       "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                       "element vertex 0\nproperty float x\nend_header\n",
                   {"m.ply:7: a second element \"vertex\""});
}

/// The triangle in `f` with its face record replaced by `face` (values as write_ply takes them).
std::string triangle_with_face(Format f, std::vector<std::vector<double>> faces,
                               const std::string& face_prop = "list uchar int vertex_indices") {
  const Elem vertex{"vertex", {"float x", "float y", "float z"}, {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  return write_ply(f, {vertex, Elem{"face", {face_prop}, std::move(faces)}});
}

size_t body_start(const std::string& ply) { return ply.find("end_header\n") + 11; }

TEST(PlyErrors, AFileClaimingGigabytesIsRefusedBeforeReading) {
  TempDir dir;
  const fs::path big = dir.write("big.ply", "ply\n");
  fs::resize_file(big, std::uintmax_t{2} << 30);  // sparse: nothing is written
  try {
    load_scene(dir.write("scene.json", scene_json(R"("file": "big.ply")")));
    ADD_FAILURE() << "a 2 GiB PLY file loaded";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("big.ply: the file has 2147483648 bytes, more than the "
                                         "limit of 1073741824"),
              std::string::npos)
        << e.what();
  }
}

TEST(PlyErrors, BadFacesNameTheRecord) {
  // face 1 is the second face: on line 11 in ASCII, 36 + 13 bytes into a binary body.
  expect_ply_error(triangle_with_face(Format::kAscii, {{3, 0, 1, 2}, {3, 0, 1, 3}}),
                   {"m.ply:15: face 1: vertex index 3 is out of range: the file has 3 vertices"});
  const std::string negative = triangle_with_face(Format::kLittle, {{3, 0, 1, 2}, {3, 0, -1, 2}});
  expect_ply_error(negative, {"m.ply: face 1 (byte " + std::to_string(body_start(negative) + 49) +
                              "): vertex index -1 is out of range"});
  // (4 bytes more, so that the record is not too short for a face before it is read)
  expect_ply_error(triangle_with_face(Format::kBig, {{2, 0, 1}}) + "pad!",
                   {"face 0 (byte ", "face with 2 vertices; at least 3 needed"});
  std::vector<double> big{300};
  for (int i = 0; i < 300; ++i) big.push_back(i % 3);
  expect_ply_error(triangle_with_face(Format::kLittle, {big}, "list ushort uchar vertex_indices"),
                   {"face 0 (byte ", "face with 300 vertices; at most 255"});
  expect_ply_error(triangle_with_face(Format::kAscii, {big}, "list ushort uchar vertex_indices"),
                   {"m.ply:14: face 0: face with 300 vertices"});
  expect_ply_error(triangle_with_face(Format::kAscii, {{9, 0, 1, 2}}),
                   {"m.ply:14: face 0: list \"vertex_indices\" has 9 items, but the line has only "
                    "3 values left"});
}

TEST(PlyErrors, LyingCountsAreCaughtBeforeAllocating) {
  // The header promises far more than the file holds: caught against the bytes (lines) present.
  const Elem vertex{"vertex", {"float x", "float y", "float z"}, {{0, 0, 0}}, 4000000000ull};
  expect_ply_error(write_ply(Format::kLittle, {vertex}),
                   {"m.ply:4: element \"vertex\": the header declares 4000000000 records of at "
                    "least 12 bytes each, but only 12 bytes are left"});
  expect_ply_error(write_ply(Format::kAscii, {vertex}),
                   {"m.ply:4: element \"vertex\": the header declares 4000000000 records, one "
                    "line each, but only 1 of the body's 1 non-blank lines"});
  expect_ply_error(write_ply(Format::kBig, {Elem{"edge", {"int a"}, {}, 1ull << 62}}),
                   {"m.ply:4: element \"edge\"", "of at least 4 bytes each"});
  expect_ply_error(
      write_ply(Format::kBig,
                {Elem{"vertex", {"uchar x", "uchar y", "uchar z"}, {}, 5000000000ull}}),
      {"m.ply:4: element \"vertex\": 5000000000 vertices; at most 4294967295"});
  // The elements together: a face needs its length and 3 corners (13 bytes) after the vertices.
  const Elem tri{"vertex", {"float x", "float y", "float z"}, {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  const Elem no_faces{"face", {"list uchar int vertex_indices"}, {}, 1};
  expect_ply_error(write_ply(Format::kLittle, {tri, no_faces}) + "123456789012",
                   {"m.ply:8: element \"face\": the header declares 1 record of at least 13 bytes "
                    "each, but only 12 bytes are left for them"});
}

TEST(PlyErrors, TruncatedBodiesAndBadLists) {
  const Elem tri{"vertex", {"float x", "float y", "float z"}, {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  const std::vector<std::string> props{"list uchar int vertex_indices", "uchar flags"};
  // The first face is longer than the fewest bytes, so the second runs out in its last value.
  std::string ply =
      write_ply(Format::kLittle, {tri, Elem{"face", props, {{4, 0, 1, 2, 0, 7}, {3, 0, 1, 2, 7}}}});
  ply.pop_back();
  expect_ply_error(ply, {"face 1 (byte ", "the file ends at byte " + std::to_string(ply.size()) +
                                              ", inside property \"flags\""});
  // A list length far beyond the bytes left.
  ply = write_ply(Format::kBig,
                  {tri, Elem{"face", {"list uint int vertex_indices"}, {{3, 0, 1, 2}}}});
  ply[body_start(ply) + 36] = '\x7f';
  expect_ply_error(ply, {"face 0 (byte ",
                         "list \"vertex_indices\" has 2130706435 items of 4 bytes, "
                         "but only 12 bytes are left in the file"});
  // Negative lengths, in a list the mesh does not use too.
  const Elem skipped{"vertex",
                     {"float x", "float y", "float z", "list char float extra"},
                     {{0, 0, 0, 0}, {1, 0, 0, -2, 5, 5}, {0, 1, 0, 0}}};
  expect_ply_error(write_ply(Format::kLittle, {skipped}),
                   {"vertex 1 (byte ", "list \"extra\" has a negative length, -2"});
  expect_ply_error(
      triangle_with_face(Format::kAscii, {{-3, 0, 1, 2}}, "list int int vertex_indices"),
      {"m.ply:14: face 0: list \"vertex_indices\" has a negative length, -3"});
  expect_ply_error(
      triangle_with_face(Format::kAscii, {{-3, 0, 1, 2}}),
      {"m.ply:14: face 0: property \"vertex_indices\": \"-3\" is not a value of type uchar"});
}

TEST(PlyErrors, BadNumbers) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::string> xyz{"double x", "double y", "double z",
                                     "float nx", "float ny", "float nz"};
  Elem vertex{"vertex", xyz, {{0, 0, 0, 0, 0, 1}, {1, nan, 0, 0, 0, 1}}};
  expect_ply_error(write_ply(Format::kLittle, {vertex}),
                   {"vertex 1 (byte ", "property \"y\" is nan, not a finite number"});
  vertex.rows[1] = {1e18, 0, 0, 0, 0, 1};
  expect_ply_error(write_ply(Format::kBig, {vertex}),
                   {"vertex 1 (byte ", "coordinate x = 1e+18 is beyond 1e17"});
  vertex.rows[1] = {1, 0, 0, 0, std::numeric_limits<float>::infinity(), 1};
  expect_ply_error(write_ply(Format::kLittle, {vertex}),
                   {"vertex 1 (byte ", "property \"ny\" is inf"});
  const std::string head = "ply\nformat ascii 1.0\n" + kTriangle;
  expect_ply_error(
      head.substr(0, head.find("element face")) + "end_header\n0 0 0\n1 nan 0\n0 1 0\n",
      {"m.ply:9: vertex 1: property \"y\": \"nan\" is not a finite number"});
  expect_ply_error(head + "0 0 0\n1 0\n0 1 0\n3 0 1 2\n",
                   {"m.ply:11: vertex 1: the line ends after 2 values; property \"z\" needs more"});
  expect_ply_error(head + "0 0 0\n1 0 0 0\n0 1 0\n3 0 1 2\n",
                   {"m.ply:11: vertex 1: the line has 4 values, 1 more than"});
  expect_ply_error(
      head + "0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n",
      {"m.ply:13: face 0: property \"vertex_indices\": \"1.5\" is not a value of type int"});
  expect_ply_error(head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\xc3\n", {"m.ply:13: invalid UTF-8"});
}

// The fuzzer's seeds (fuzz/make_ply_seeds.py) are what they claim: meshes that load, and files
// that each fail for their own reason.
TEST(PlyMesh, TheFuzzSeedsLoadOrFailAsNamed) {
  const fs::path seeds = fs::path(RAYFARM_SOURCE_DIR) / "fuzz" / "corpus" / "ply";
  TempDir dir;
  const auto load = [&](const std::string& name) {
    return load_ply_scene(dir, testing::read_file(seeds / name));
  };
  for (const std::string name : {"cube-ascii.ply", "cube-le.ply"}) {
    const Scene scene = load(name);
    EXPECT_TRUE(scene.warnings.empty()) << name;
    EXPECT_EQ(scene.meshes.at(0).triangle_count(), 12u) << name;
  }
  EXPECT_EQ(load("cube-ascii.ply").meshes[0].normals.size(), 8u);
  EXPECT_EQ(load("tri-be.ply").meshes.at(0).triangle_count(), 4u);
  EXPECT_EQ(load("tri-be.ply").meshes[0].uvs.size(), 5u);
  EXPECT_NE(load("trailing-le.ply").warnings.at(0).find("14 byte(s) after the last element"),
            std::string::npos);
  const std::pair<const char*, const char*> broken[] = {
      {"truncated-le.ply", "bytes are left"},
      {"lying-count.ply", "4000000000 records"},
      {"negative-list.ply", "negative length, -3"},
      {"no-format.ply", "element before any format line"}};
  for (const auto& [name, what] : broken) {
    try {
      load(name);
      ADD_FAILURE() << name << " loaded";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }
}

TEST(PlyMesh, ABundleCarriesThePlyFile) {
  TempDir dir;
  dir.write("meshes/m.ply", write_ply(Format::kLittle, sample_mesh()));
  const fs::path scene = dir.write("scene.json", scene_json(R"("file": "meshes/m.ply")"));
  const PackedScene packed = pack_scene(scene);
  std::vector<std::string> paths;
  for (const BundleFile& f : packed.bundle.files) paths.push_back(f.path);
  std::sort(paths.begin(), paths.end());
  EXPECT_EQ(paths, (std::vector<std::string>{"meshes/m.ply", "scene.json"}));
  for (const BundleFile& f : packed.bundle.files) {
    if (f.path == "meshes/m.ply") {
      EXPECT_EQ(f.data, testing::read_file(dir.path() / "meshes/m.ply"));
    }
  }
}

}  // namespace
}  // namespace rayfarm
