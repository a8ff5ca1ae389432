// A PLY mesh renders exactly as the same mesh written as OBJ: the two readers hand the renderer
// the same triangles, so the images' fixed-point sums agree bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <sstream>
#include <string>

#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"
#include "renderer/renderer.h"

namespace rayfarm {
namespace {

constexpr float kCorners[8][3] = {{-1, -1, -1}, {1, -1, -1}, {-1, 1, -1}, {1, 1, -1},
                                  {-1, -1, 1},  {1, -1, 1},  {-1, 1, 1},  {1, 1, 1}};
constexpr uint32_t kQuads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                   {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};

std::string cube_obj() {
  std::ostringstream obj;
  for (const auto& c : kCorners) obj << "v " << c[0] << " " << c[1] << " " << c[2] << "\n";
  for (const auto& q : kQuads)
    obj << "f " << q[0] + 1 << " " << q[1] + 1 << " " << q[2] + 1 << " " << q[3] + 1 << "\n";
  return obj.str();
}

/// The cube as a binary little-endian PLY with a vertex colour the reader skips.
std::string cube_ply() {
  std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 8\nproperty float x\n"
      "property float y\nproperty float z\nproperty uchar red\nelement face 6\n"
      "property list uchar uint vertex_indices\nend_header\n";
  auto put = [&](const void* p, size_t n) {
    unsigned char raw[4];
    std::memcpy(raw, p, n);
    if (std::endian::native == std::endian::big) std::reverse(raw, raw + n);
    ply.append(reinterpret_cast<const char*>(raw), n);
  };
  const unsigned char red = 200, four = 4;
  for (const auto& c : kCorners) {
    for (float v : c) put(&v, 4);
    put(&red, 1);
  }
  for (const auto& q : kQuads) {
    put(&four, 1);
    for (uint32_t i : q) put(&i, 4);
  }
  return ply;
}

TileResult render(const testing::TempDir& dir, const std::string& mesh_file) {
  const Scene scene = load_scene(dir.write("scene-" + mesh_file + ".json", R"({
    "camera": {"eye": [2.5, 2, -4], "look_at": [0, 0, 0], "fov_y": 40},
    "film": {"width": 16, "height": 16},
    "materials": {"m": {"type": "diffuse", "albedo": [0.7, 0.5, 0.3]},
                  "floor": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
    "shapes": [{"type": "mesh", "file": ")" + mesh_file + R"(", "material": "m",
                "transform": {"rotate": {"axis": [0, 1, 0], "angle": 20}}},
               {"type": "quad", "corner": [-5, -1, -5], "edge1": [0, 0, 10], "edge2": [10, 0, 0],
                "material": "floor"}],
    "lights": [{"type": "point", "position": [2, 4, -3], "intensity": [20, 20, 20]}],
    "render": {"spp": 4, "max_depth": 4, "integrator": "nee", "seed": 7}})"));
  EXPECT_TRUE(scene.warnings.empty());
  Renderer renderer(scene, scene.render);
  return renderer.render({0, 0, 16, 16}, {0, 4});
}

TEST(PlyRender, APlyMeshRendersAsTheSameObjMesh) {
  testing::TempDir dir;
  dir.write("cube.obj", cube_obj());
  dir.write("cube.ply", cube_ply());
  const TileResult obj = render(dir, "cube.obj");
  const TileResult ply = render(dir, "cube.ply");
  EXPECT_EQ(ply.nonfinite, 0u);
  EXPECT_EQ(ply.sum, obj.sum);
  EXPECT_EQ(ply.sum_sq, obj.sum_sq);
  Fixed total = 0;
  for (Fixed v : ply.sum) total += v;
  EXPECT_GT(total, 0);
}

}  // namespace
}  // namespace rayfarm
