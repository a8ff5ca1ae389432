#include "common/scene/gltf_nodes.h"

#include <algorithm>
#include <cmath>

#include "common/limits.h"
#include "common/math/transform.h"
#include "common/math/wide.h"
#include "common/scene/instances.h"
#include "common/scene/json_reader.h"
#include "common/scene/transform_reader.h"

namespace rayfarm::gltf {

namespace {

/// Luminous efficacy that turns the extension's photometric units into rayfarm's radiometric
/// ones: candela to W/sr, lux to W/m^2 (docs/gltf.md, "Lights").
constexpr double kLumensPerWatt = 683.0;

std::string node_name(int index) { return "nodes[" + std::to_string(index) + "]"; }

Vec3 to_vec3(const WideVec3& v) {
  return {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
}

bool in_range(const WideVec3& p) {
  return std::fabs(p.x) <= kMaxCoordinate && std::fabs(p.y) <= kMaxCoordinate &&
         std::fabs(p.z) <= kMaxCoordinate;
}

class NodeReader {
 public:
  NodeReader(const Source& src, Materials& materials, const GltfOptions& options, Scene& scene)
      : src_(src),
        model_(*src.model),
        materials_(materials),
        options_(options),
        scene_(scene),
        context_{src.display, &scene.warnings},
        parents_(model_.nodes.size(), 0) {}

  GltfResult read() {
    std::vector<int> roots;
    if (!model_.scenes.empty()) {
      const int s = model_.defaultScene >= 0 ? model_.defaultScene : 0;
      if (static_cast<size_t>(s) >= model_.scenes.size())
        src_.fail("scene", "scene " + std::to_string(s) + " does not exist");
      roots = model_.scenes[static_cast<size_t>(s)].nodes;
    } else {
      // Without scenes, every node that is no other's child is a root.
      std::vector<uint8_t> child(model_.nodes.size(), 0);
      for (const tinygltf::Node& n : model_.nodes) {
        for (int c : n.children) {
          if (c >= 0 && static_cast<size_t>(c) < child.size()) child[static_cast<size_t>(c)] = 1;
        }
      }
      for (size_t i = 0; i < child.size(); ++i) {
        if (!child[i]) roots.push_back(static_cast<int>(i));
      }
    }
    by_index_ = camera_by_index();
    for (int root : roots) visit(root, Transform(), "scene", 0);
    for (const Placement& p : placements_) place(p);
    if (!options_.camera.empty() && !result_.has_camera) {
      throw SceneError(src_.display + ": no camera named \"" + options_.camera +
                       "\" placed by the scene's nodes (a camera's name, its node's name, or its " +
                       "index in cameras: the file has " + std::to_string(model_.cameras.size()) +
                       ", numbered from 0)");
    }
    return result_;
  }

 private:
  void visit(int index, const Transform& parent, const std::string& from, int depth) {
    if (index < 0 || static_cast<size_t>(index) >= model_.nodes.size())
      src_.fail(from, "node " + std::to_string(index) + " does not exist");
    const std::string where = node_name(index);
    // A node has at most one parent: this also rules out cycles, and bounds the walk.
    if (parents_[static_cast<size_t>(index)]++ != 0)
      src_.fail(where, "is reached twice (a node may have only one parent, and no cycles)");
    if (depth > kMaxJsonNesting) src_.fail(where, "nodes nest deeper than 64 levels");
    if (++visited_ > kMaxGltfNodes) src_.fail(where, "more than 2^20 nodes");
    const tinygltf::Node& node = model_.nodes[static_cast<size_t>(index)];
    const Transform world = local_transform(node, where).then(parent);
    if (node.mesh >= 0) note_mesh(node, index, world, where);
    if (node.camera >= 0) consider_camera(node, world, where);
    if (auto it = node.extensions.find("KHR_lights_punctual"); it != node.extensions.end())
      add_light(it->second, world, where + "/extensions/KHR_lights_punctual");
    for (int child : node.children) visit(child, world, where + "/children", depth + 1);
  }

  Transform local_transform(const tinygltf::Node& node, const std::string& where) const {
    auto finite = [&](const std::vector<double>& v, const char* what) {
      for (double x : v) {
        if (!std::isfinite(x) || std::fabs(x) > kMaxCoordinate)
          src_.fail(where + "/" + what, "numbers must be finite, of magnitude at most 1e17");
      }
    };
    if (!node.matrix.empty()) {
      if (node.matrix.size() != 16) src_.fail(where + "/matrix", "expected 16 numbers");
      finite(node.matrix, "matrix");
      const auto& m = node.matrix;  // column-major
      if (m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0)
        src_.fail(where + "/matrix", "not an affine transform (its last row is not 0 0 0 1)");
      return Transform(
          {m[0], m[4], m[8], m[12], m[1], m[5], m[9], m[13], m[2], m[6], m[10], m[14]});
    }
    Transform t;
    if (!node.scale.empty()) {
      if (node.scale.size() != 3) src_.fail(where + "/scale", "expected 3 numbers");
      finite(node.scale, "scale");
      t = Transform::scale({node.scale[0], node.scale[1], node.scale[2]});
    }
    if (!node.rotation.empty()) {
      if (node.rotation.size() != 4) src_.fail(where + "/rotation", "expected 4 numbers");
      finite(node.rotation, "rotation");
      double x = node.rotation[0], y = node.rotation[1], z = node.rotation[2], w = node.rotation[3];
      const double len = std::sqrt(x * x + y * y + z * z + w * w);
      if (!(len > 0.0)) src_.fail(where + "/rotation", "the quaternion is zero");
      x /= len, y /= len, z /= len, w /= len;
      t = t.then(Transform({1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w), 0,
                            2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w), 0,
                            2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y), 0}));
    }
    if (!node.translation.empty()) {
      if (node.translation.size() != 3) src_.fail(where + "/translation", "expected 3 numbers");
      finite(node.translation, "translation");
      t = t.then(
          Transform::translate({node.translation[0], node.translation[1], node.translation[2]}));
    }
    return t;
  }

  // Meshes are placed once the walk has counted every node that uses them: a mesh placed by one
  // node becomes world meshes, one placed by several a group (its primitives stored once, in
  // object space) with an instance per node.
  struct Placement {
    int mesh;
    int node;
    Transform world;
  };

  void note_mesh(const tinygltf::Node& node, int index, const Transform& world,
                 const std::string& where) {
    if (static_cast<size_t>(node.mesh) >= model_.meshes.size())
      src_.fail(where + "/mesh", "mesh " + std::to_string(node.mesh) + " does not exist");
    if (node.skin >= 0 && !warned_skin_) {
      warned_skin_ = true;
      src_.warn(where + "/skin", "skins are not supported; the mesh is rendered in its bind pose");
    }
    uses_.resize(model_.meshes.size(), 0);
    ++uses_[static_cast<size_t>(node.mesh)];
    placements_.push_back({node.mesh, index, world});
  }

  /// The mesh's primitives in its own space, empty ones left out.
  std::vector<TriangleMesh> read_mesh(int index) {
    const tinygltf::Mesh& mesh = model_.meshes[static_cast<size_t>(index)];
    std::vector<TriangleMesh> out;
    for (size_t p = 0; p < mesh.primitives.size(); ++p) {
      const std::string at =
          "meshes[" + std::to_string(index) + "]/primitives[" + std::to_string(p) + "]";
      TriangleMesh m = primitive(mesh.primitives[p], at);
      if (m.triangle_count() > 0) out.push_back(std::move(m));
    }
    return out;
  }

  void place(const Placement& p) {
    const std::string where = node_name(p.node);
    const double det = p.world.determinant();
    // A singular placement flattens the mesh: as world triangles it is seen edge on, if at all.
    if (uses_[static_cast<size_t>(p.mesh)] < 2 || !(std::fabs(det) > 0.0) || !std::isfinite(det)) {
      for (TriangleMesh& m : read_mesh(p.mesh)) {
        if (!p.world.is_identity()) {
          const scene_json::Json none;
          transform_mesh(m, p.world, scene_json::Node(none, context_, "/" + where));
        }
        scene_.meshes.push_back(std::move(m));
      }
      return;
    }
    group_of_.resize(model_.meshes.size(), -1);
    int& group = group_of_[static_cast<size_t>(p.mesh)];
    const bool first = group < 0;
    if (first) {
      MeshGroup g;
      g.name = src_.display + " meshes[" + std::to_string(p.mesh) + "]";
      g.meshes = read_mesh(p.mesh);
      group = static_cast<int>(scene_.groups.size());
      scene_.groups.push_back(std::move(g));
      made_.push_back({{}, {}, group_emits(scene_, scene_.groups.back())});
      group_box(scene_.groups.back(), made_.back().lo, made_.back().hi);
    }
    const MeshGroup& g = scene_.groups[static_cast<size_t>(group)];
    const MadeGroup& made = made_[static_cast<size_t>(group) - first_group_];
    if (g.meshes.empty()) return;
    if (scene_.instances.size() >= kMaxInstances)
      src_.fail(where, "more than 2^20 instances (placements of meshes that several nodes use)");
    const uint64_t triangles = group_triangle_count(g);
    // The renderer places an emissive group's instances as world triangles (area lights need
    // them): each placement after the first is stored again, and counts so.
    if (!first && made.emits) {
      triangles_ += triangles;
      if (triangles_ > kMaxGltfTriangles)
        src_.fail(where,
                  "the file's meshes hold more than 2^26 triangles (an emissive mesh "
                  "counts once per node that places it)");
    }
    placed_ += triangles;
    if (placed_ > kMaxInstancedTriangles)
      src_.fail(where, "the nodes place more than 2^36 triangles in all");
    if (!box_placed_in_range(made.lo, made.hi, p.world))
      src_.fail(where, "places the mesh's points beyond 1e17, the largest coordinate handled");
    Instance instance;
    instance.group = static_cast<uint32_t>(group);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) instance.world_from_object[4 * r + c] = p.world.at(r, c);
    scene_.instances.push_back(instance);
  }

  TriangleMesh primitive(const tinygltf::Primitive& prim, const std::string& at) {
    TriangleMesh out;
    out.origin = src_.display + " " + at;
    if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        prim.mode != TINYGLTF_MODE_TRIANGLE_FAN && prim.mode != -1) {
      src_.warn(at + "/mode", "points and lines are not rendered");
      return out;
    }
    if (!prim.targets.empty() && !warned_morph_) {
      warned_morph_ = true;
      src_.warn(at + "/targets", "morph targets are not supported; the base shape is rendered");
    }
    const auto position = prim.attributes.find("POSITION");
    if (position == prim.attributes.end()) src_.fail(at + "/attributes", "no POSITION");
    // What the primitive will hold, against the file's limits, before any of it is read: its
    // accessors may share one large buffer, or declare counts without one.
    const size_t declared = accessor_count(src_, position->second, at + "/attributes/POSITION");
    vertices_ += declared;
    if (vertices_ > kMaxGltfVertices)
      src_.fail(at + "/attributes/POSITION", "the file's meshes hold more than 2^26 vertices");
    const size_t corners =
        prim.indices >= 0 ? accessor_count(src_, prim.indices, at + "/indices") : declared;
    const bool list = prim.mode == TINYGLTF_MODE_TRIANGLES || prim.mode == -1;
    if (triangles_ + (list ? corners / 3 : corners) > kMaxGltfTriangles)
      src_.fail(at, "the file's meshes hold more than 2^26 triangles");
    out.positions = read_vec3(src_, position->second, at + "/attributes/POSITION");
    for (const Vec3& p : out.positions) {
      if (!(std::fabs(p.x) <= kMaxCoordinate && std::fabs(p.y) <= kMaxCoordinate &&
            std::fabs(p.z) <= kMaxCoordinate))
        src_.fail(at + "/attributes/POSITION", "a position's magnitude exceeds 1e17");
    }
    const size_t n = out.positions.size();
    std::vector<uint32_t> index =
        prim.indices >= 0 ? read_indices(src_, prim.indices, n, at) : std::vector<uint32_t>();
    if (prim.indices < 0) {
      index.resize(n);
      for (size_t i = 0; i < n; ++i) index[i] = static_cast<uint32_t>(i);
    }
    out.indices = triangles(index, prim.mode);
    triangles_ += out.indices.size() / 3;
    if (triangles_ > kMaxGltfTriangles)
      src_.fail(at, "the file's meshes hold more than 2^26 triangles");

    auto same_count = [&](size_t count, const char* what) {
      if (count != n)
        src_.fail(at + "/attributes/" + what,
                  std::to_string(count) + " elements, but POSITION has " + std::to_string(n));
    };
    if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
      out.normals = read_vec3(src_, it->second, at + "/attributes/NORMAL");
      same_count(out.normals.size(), "NORMAL");
      for (Vec3& v : out.normals) {
        const double len = length(wide(v));
        v = len > 0.0 ? to_vec3({v.x / len, v.y / len, v.z / len}) : Vec3(0.f);
      }
    }
    const uint32_t material = materials_.material(prim.material);
    out.materials.assign(out.indices.size() / 3, material);
    const Material& mat = scene_.materials[material];
    // A material that the JSON scene replaces may read what the glTF's own does not.
    const bool replaced = options_.replaced_materials.count(mat.name) > 0;
    if (mat.normal_map || replaced) {
      if (auto it = prim.attributes.find("TANGENT"); it != prim.attributes.end()) {
        out.tangents = read_vec4(src_, it->second, at + "/attributes/TANGENT");
        same_count(out.tangents.size(), "TANGENT");
        for (Vec4& t : out.tangents) {
          const double len = std::sqrt(double(t.x) * t.x + double(t.y) * t.y + double(t.z) * t.z);
          // Exporters write zero tangents where the texture coordinates are degenerate; the
          // renderer derives the frame there instead.
          const float w = t.w < 0.f ? -1.f : 1.f;
          t = len > 0.0 ? Vec4(float(t.x / len), float(t.y / len), float(t.z / len), w)
                        : Vec4(0.f, 0.f, 0.f, w);
        }
      }
    }
    if (auto it = prim.attributes.find("COLOR_0"); it != prim.attributes.end() && !replaced) {
      // It multiplies the base colour of the material, which from now on reads vertex colours.
      bool alpha = false;
      out.colours = read_colours(src_, it->second, n, at + "/attributes/COLOR_0", alpha);
      Material& m = scene_.materials[material];
      m.vertex_colours = true;
      if (alpha && (m.has_alpha() || m.alpha_blend) && !warned_vertex_alpha_) {
        warned_vertex_alpha_ = true;
        src_.warn(at + "/attributes/COLOR_0",
                  "the vertex colours' alpha is not read: coverage is the material's alone");
      }
    }
    if (mat.uses_uv() || replaced) {
      const std::string set = "TEXCOORD_" + std::to_string(materials_.texcoord(prim.material));
      if (auto it = prim.attributes.find(set); it != prim.attributes.end()) {
        out.uvs = read_vec2(src_, it->second, at + "/attributes/" + set);
        same_count(out.uvs.size(), set.c_str());
      } else if (!replaced) {
        src_.warn(at + "/attributes", "no " + set + " for its textured material; the " +
                                          "textures are read at the triangles' barycentrics");
      }
    }
    return out;
  }

  /// Triangle list indices from a primitive's indices in its mode.
  std::vector<uint32_t> triangles(const std::vector<uint32_t>& index, int mode) const {
    if (mode == TINYGLTF_MODE_TRIANGLES || mode == -1) {
      std::vector<uint32_t> out(index.begin(), index.end() - static_cast<long>(index.size() % 3));
      return out;
    }
    std::vector<uint32_t> out;
    for (size_t i = 2; i < index.size(); ++i) {
      if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
        out.insert(out.end(), {index[0], index[i - 1], index[i]});
      } else if (i % 2 == 0) {  // a strip alternates its winding
        out.insert(out.end(), {index[i - 2], index[i - 1], index[i]});
      } else {
        out.insert(out.end(), {index[i - 1], index[i - 2], index[i]});
      }
    }
    return out;
  }

  /// Whether --camera (gltf.camera) gives an index into the file's cameras: digits that name no
  /// camera or camera node (a name wins, so that a camera named "2" stays reachable).
  bool camera_by_index() const {
    const std::string& c = options_.camera;
    if (c.empty() || c.size() > 9 ||
        !std::all_of(c.begin(), c.end(), [](char ch) { return ch >= '0' && ch <= '9'; }))
      return false;
    for (const tinygltf::Camera& cam : model_.cameras)
      if (cam.name == c) return false;
    for (const tinygltf::Node& n : model_.nodes)
      if (n.camera >= 0 && n.name == c) return false;
    return true;
  }

  void consider_camera(const tinygltf::Node& node, const Transform& world,
                       const std::string& where) {
    if (static_cast<size_t>(node.camera) >= model_.cameras.size())
      src_.fail(where + "/camera", "camera " + std::to_string(node.camera) + " does not exist");
    const tinygltf::Camera& cam = model_.cameras[static_cast<size_t>(node.camera)];
    if (result_.has_camera) return;
    if (!options_.camera.empty() && options_.camera != cam.name && options_.camera != node.name &&
        !(by_index_ && options_.camera == std::to_string(node.camera)))
      return;
    const std::string at = "cameras[" + std::to_string(node.camera) + "]";
    Camera c;
    if (cam.type == "perspective") {
      const double yfov = cam.perspective.yfov;
      if (!(yfov > 0.0 && yfov < 3.14159))
        src_.fail(at + "/perspective/yfov", "must lie in (0, pi)");
      c.fov_y_deg = static_cast<float>(yfov * 180.0 / 3.14159265358979323846);
      if (cam.perspective.aspectRatio > 0.0 && std::isfinite(cam.perspective.aspectRatio))
        result_.aspect = cam.perspective.aspectRatio;
    } else if (cam.type == "orthographic") {
      const double x = std::fabs(cam.orthographic.xmag), y = std::fabs(cam.orthographic.ymag);
      if (!(y > 0.0 && y <= kMaxCoordinate && x > 0.0 && x <= kMaxCoordinate))
        src_.fail(at + "/orthographic", "xmag and ymag must be non-zero, at most 1e17");
      c.projection = Camera::Projection::kOrthographic;
      c.view_height = static_cast<float>(2.0 * y);
      result_.aspect = x / y;
    } else {
      src_.fail(at + "/type", "unknown camera type \"" + cam.type + "\"");
    }
    // A glTF camera looks down its node's -z with +y up; the node's scale is ignored.
    const WideVec3 eye = world.point({0, 0, 0});
    const WideVec3 forward = world.vector({0, 0, -1});
    const WideVec3 up = world.vector({0, 1, 0});
    const double f = length(forward);
    if (!in_range(eye)) src_.fail(where, "the camera lies farther out than 1e17");
    if (!(f > 0.0) || !(length(up) > 0.0)) src_.fail(where, "the camera's transform is singular");
    c.eye = to_vec3(eye);
    c.look_at = to_vec3({eye.x + forward.x / f, eye.y + forward.y / f, eye.z + forward.z / f});
    c.up = to_vec3(up);
    if (c.eye == c.look_at)
      src_.fail(where, "the camera lies so far out that its view direction is lost in rounding");
    scene_.camera = c;
    result_.has_camera = true;
  }

  void add_light(const tinygltf::Value& ext, const Transform& world, const std::string& at) {
    if (!ext.IsObject() || !ext.Has("light") || !ext.Get("light").IsInt())
      src_.fail(at, "expected {\"light\": index}");
    const int index = ext.Get("light").GetNumberAsInt();
    if (index < 0 || static_cast<size_t>(index) >= model_.lights.size())
      src_.fail(at + "/light", "light " + std::to_string(index) + " does not exist");
    const tinygltf::Light& l = model_.lights[static_cast<size_t>(index)];
    const std::string where = "extensions/KHR_lights_punctual/lights/" + std::to_string(index);
    float color[3] = {1.f, 1.f, 1.f};
    if (!l.color.empty()) {
      if (l.color.size() != 3) src_.fail(where + "/color", "expected 3 numbers");
      for (size_t c = 0; c < 3; ++c) {
        if (!(l.color[c] >= 0.0 && l.color[c] <= 1.0))
          src_.fail(where + "/color", "components must lie in [0, 1]");
        color[c] = static_cast<float>(l.color[c]);
      }
    }
    if (!(l.intensity >= 0.0 && l.intensity <= 1e12))
      src_.fail(where + "/intensity", "must lie in [0, 1e12]");
    const float power = static_cast<float>(l.intensity / kLumensPerWatt);
    const Vec3 radiometric(color[0] * power, color[1] * power, color[2] * power);
    const WideVec3 axis = world.vector({0, 0, -1});
    const double len = length(axis);
    if (l.type == "directional") {
      if (!(len > 0.0)) src_.fail(at, "the light's transform is singular");
      DirectionalLight d;
      d.direction = to_vec3({axis.x / len, axis.y / len, axis.z / len});
      d.irradiance = radiometric;
      scene_.directional_lights.push_back(d);
      return;
    }
    const WideVec3 origin = world.point({0, 0, 0});
    if (!in_range(origin)) src_.fail(at, "the light lies farther out than 1e17");
    const Vec3 position = to_vec3(origin);
    if (l.type == "point") {
      scene_.point_lights.push_back({position, radiometric});
      return;
    }
    if (l.type != "spot") src_.fail(where + "/type", "unknown light type \"" + l.type + "\"");
    const double inner = l.spot.innerConeAngle, outer = l.spot.outerConeAngle;
    if (!(inner >= 0.0 && inner < outer && outer <= 3.14159265358979323846 / 2))
      src_.fail(where + "/spot", "cone angles must satisfy 0 <= inner < outer <= pi/2");
    if (!(len > 0.0)) src_.fail(at, "the light's transform is singular");
    SpotLight s;
    s.position = position;
    s.direction = to_vec3({axis.x / len, axis.y / len, axis.z / len});
    s.intensity = radiometric;
    s.cutoff_deg = static_cast<float>(outer * 180.0 / 3.14159265358979323846);
    s.beam_width_deg = static_cast<float>(inner * 180.0 / 3.14159265358979323846);
    scene_.spot_lights.push_back(s);
  }

  const Source& src_;
  const tinygltf::Model& model_;
  Materials& materials_;
  const GltfOptions& options_;
  Scene& scene_;
  scene_json::Context context_;
  std::vector<uint32_t> parents_;
  size_t visited_ = 0;
  uint64_t vertices_ = 0;       // stored, as triangles_
  uint64_t triangles_ = 0;      // stored: a mesh used by several nodes counts once
  uint64_t placed_ = 0;         // placed by instances: a mesh counts once per node
  std::vector<uint32_t> uses_;  // per mesh: the nodes that place it
  std::vector<int> group_of_;   // per mesh used more than once: its group, once made
  std::vector<Placement> placements_;
  // What each group made here needs for every placement, found once: its box, and whether it
  // emits (a group's points and materials are read once, not once per node).
  struct MadeGroup {
    WideVec3 lo, hi;
    bool emits;
  };
  std::vector<MadeGroup> made_;
  const size_t first_group_ = scene_.groups.size();  // groups already in the scene
  bool warned_skin_ = false, warned_morph_ = false;
  bool by_index_ = false;  // camera_by_index(), found once
  bool warned_vertex_alpha_ = false;
  GltfResult result_;
};

}  // namespace

GltfResult read_nodes(const Source& src, Materials& materials, const GltfOptions& options,
                      Scene& scene) {
  return NodeReader(src, materials, options, scene).read();
}

}  // namespace rayfarm::gltf
