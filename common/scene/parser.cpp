// The JSON scene format (docs/scene-format.md): the scene's sections, one at a time, each value
// read through json_reader.h so that every message can say where the problem is.
#include "common/scene/parser.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string_view>
#include <variant>

#include "common/limits.h"
#include "common/math/wide.h"
#include "common/scene/animation.h"
#include "common/scene/camera_reader.h"
#include "common/scene/film_reader.h"
#include "common/scene/instances.h"
#include "common/scene/json_reader.h"
#include "common/scene/light_reader.h"
#include "common/scene/material_reader.h"
#include "common/scene/mitsuba_loader.h"
#include "common/scene/obj_loader.h"
#include "common/scene/ply_loader.h"
#include "common/scene/render_reader.h"
#include "common/scene/texture_reader.h"
#include "common/scene/transform_reader.h"
#include "common/util/text.h"

namespace rayfarm {
namespace fs = std::filesystem;

namespace {

using namespace scene_json;  // NOLINT(google-build-using-namespace): the JSON readers

/// Length of the cross product, in double so that coordinates up to 1e30 cannot overflow.
double cross_length(const Vec3& a, const Vec3& b) { return length(cross(wide(a), wide(b))); }

// ---- the scene -------------------------------------------------------------------------------

/// Fills a Scene from the parsed JSON, one top-level section at a time.
class SceneReader {
  double frame_offset_;  // the pose's time after the frame, in frames (motion blur)

 public:
  SceneReader(Scene* scene, const Context& context, fs::path folder, const SceneCheck& check,
              SceneImages images, double frame_offset)
      : frame_offset_(frame_offset),
        scene_(*scene),
        context_(context),
        folder_(std::move(folder)),
        check_(check),
        images_(images),
        textures_(folder_, images) {}

  void read(const Node& root) {
    root.allow_keys({"format", "gltf", "camera", "film", "textures", "materials", "groups",
                     "shapes", "lights", "background", "render", "animation"});
    if (auto n = root.find("format")) read_format(*n);
    // The film and the render settings first: the caller's limits on them come before the rest.
    // A scene built on a glTF file may leave the film to the glTF camera's aspect ratio.
    const auto film = root.find("film");
    const auto gltf = root.find("gltf");
    if (film || !gltf) read_film(root.require("film"));
    if (auto n = root.find("render")) read_render_settings(*n, scene_.render);
    if (film && check_) {
      if (auto refusal = check_(scene_.film, scene_.render)) throw SceneRefused(*refusal);
    }
    bool has_camera = false;
    if (gltf) {
      const GltfResult result = read_gltf(*gltf, root.find("materials"));
      has_camera = result.has_camera;
      if (!film) {
        scene_.film = default_gltf_film(result.aspect);
        if (check_) {
          if (auto refusal = check_(scene_.film, scene_.render)) throw SceneRefused(*refusal);
        }
      }
    }
    // A glTF file's camera, else the scene's "camera"; with neither, a glTF scene gets the view a
    // direct render of the file gets (once every shape is read, below).
    if (auto n = root.find("camera"); n || !gltf)
      scene_.camera = read_camera(root.require("camera"));
    if (auto n = root.find("textures")) textures_.read(*n, scene_.textures, scene_.referenced);
    if (auto n = root.find("materials")) read_materials(*n);
    if (auto n = root.find("groups")) read_groups(*n);
    if (auto n = root.find("shapes")) read_shapes(*n);
    if (auto n = root.find("lights")) read_lights(*n, folder_, images_, textures_, scene_);
    if (auto n = root.find("background")) scene_.background = read_radiance(*n);
    if (gltf && !has_camera && !root.find("camera")) {
      scene_.camera = default_view(scene_);
      scene_.default_camera = true;
      root.warn(std::string("no \"camera\", and the glTF file has none") + kDefaultViewWarning);
    }
  }

 private:
  static void read_format(const Node& n) {
    const int64_t format = read_integer(n, 1, INT64_MAX);
    if (format > kSceneFormatVersion) {
      n.fail("scene format " + std::to_string(format) + " is newer than format " +
             std::to_string(kSceneFormatVersion) + ", the newest this build reads");
    }
  }

  void read_film(const Node& n) {
    n.allow_keys({"width", "height", "filter", "sample_border"});
    const int64_t width = read_integer(n.require("width"), 1, kMaxFilmSide);
    const int64_t height = read_integer(n.require("height"), 1, kMaxFilmSide);
    if (width * height > kMaxFilmPixels) {
      n.fail("film " + std::to_string(width) + "x" + std::to_string(height) + " has " +
             std::to_string(width * height) + " pixels, more than the limit of " +
             std::to_string(kMaxFilmPixels) + " (2^26)");
    }
    scene_.film = {static_cast<uint32_t>(width), static_cast<uint32_t>(height)};
    scene_.filter = read_pixel_filter(n.find("filter"), n.find("sample_border"));
  }

  // ---- materials ----

  void read_materials(const Node& n) {
    for (const auto& [name, value] : n.object().items()) {
      const Node m = n.child(name);
      if (name.empty()) m.fail("a material name must not be empty");
      if (auto it = material_index_.find(name); it != material_index_.end()) {
        scene_.materials[it->second] = read_material(m, name);  // overrides the glTF's
        continue;
      }
      add_material(read_material(m, name));
    }
  }

  // ---- glTF ----

  /// "gltf": {"file": NAME, "camera": NAME, "time": SECONDS}: the file's meshes, materials
  /// (which "materials" may then override by name) and lights join the scene.
  GltfResult read_gltf(const Node& n, const std::optional<Node>& materials) {
    n.allow_keys({"file", "camera", "time"});
    const Node file = n.require("file");
    const fs::path relative = mesh_path(file);
    if (!is_gltf_path(relative)) file.fail("expected a .gltf or .glb file");
    GltfOptions options;
    if (auto c = n.find("camera")) options.camera = read_string(*c);
    // A still scene may pose the file's animations at a time of its choosing.
    if (auto t = n.find("time")) {
      if (scene_.animation) t->fail("an animated scene poses the file at its frames' times");
      const double seconds = read_number(*t);
      if (!(seconds >= 0.0 && seconds <= 1e9)) t->fail("expected seconds from 0 to 1e9");
      options.time = seconds;
    }
    // An animated scene poses the file's nodes at its frame's time, its first frame at time 0.
    if (scene_.frame) {
      options.time =
          (double(*scene_.frame - scene_.animation->first) + frame_offset_) / scene_.animation->fps;
    }
    if (materials)
      for (const auto& [name, value] : materials->object().items())
        options.replaced_materials.insert(name);
    const size_t instances_before = scene_.instances.size();
    const GltfResult result = load_gltf(folder_, relative, options, images_, scene_);
    // The file's instances count towards the scene's placed triangles, as the JSON ones do.
    for (size_t i = instances_before; i < scene_.instances.size(); ++i)
      if (auto refusal = instance_budget_.add(scene_, scene_.instances[i].group))
        file.fail(*refusal);
    for (uint32_t i = 0; i < scene_.materials.size(); ++i)
      material_index_.try_emplace(scene_.materials[i].name, i);
    return result;
  }

  /// Adds a material, or returns the index of the one already named so.
  uint32_t add_material(Material m) {
    const auto [it, added] = material_index_.try_emplace(m.name, uint32_t(scene_.materials.size()));
    if (added) scene_.materials.push_back(std::move(m));
    return it->second;
  }

  Material read_material(const Node& n, const std::string& name) const {
    const Node type = n.require("type");
    // Both sides of every opaque kind reflect already: the wrapper is the identity.
    if (read_string(type) == "twosided") {
      n.allow_keys({"type", "material"});
      Material m = read_material(n.require("material"), name);
      m.one_sided = false;
      return m;
    }
    Material m;
    m.name = name;
    const uint64_t textured_before = textures_.textured_reads();
    if (!read_material_kind(n, read_string(type), m.kind, textures_)) {
      type.fail("unknown material type " + as_written(type.json()) + "; expected one of " +
                material_type_names() + ", twosided");
    }
    m.textured = textures_.textured_reads() != textured_before;
    read_surface(n, m, textures_, scene_.textures);
    return m;
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
    for (size_t i = 0; i < n.array().size(); ++i)
      read_shape(n.child(i), "shapes[" + std::to_string(i) + "]", false);
  }

  // A shape of "shapes", or of a group's list when `in_group`.
  void read_shape(const Node& shape, const std::string& origin, bool in_group) {
    const Node type = shape.require("type");
    const std::string kind = read_string(type);
    if (in_group && (kind == "sphere" || kind == "instance")) {
      type.fail("a group holds meshes, quads and triangles only, not " + as_written(type.json()) +
                " (a sphere or an instance goes in \"shapes\")");
    }
    if (kind == "mesh")
      read_mesh(shape);
    else if (kind == "sphere")
      read_sphere(shape);
    else if (kind == "quad")
      read_quad(shape, origin);
    else if (kind == "triangle")
      read_triangle(shape, origin);
    else if (kind == "instance")
      read_instance(shape);
    else
      type.fail("unknown shape type " + as_written(type.json()) +
                "; expected one of mesh, sphere, quad, triangle, instance");
  }

  // ---- groups and instances ----

  void read_groups(const Node& n) {
    for (const auto& [name, value] : n.object().items()) {
      const Node shapes = n.child(name);
      MeshGroup group;
      group.name = name;
      meshes_ = &group.meshes;
      for (size_t i = 0; i < shapes.array().size(); ++i) {
        read_shape(shapes.child(i), "groups/" + name + "[" + std::to_string(i) + "]", true);
      }
      meshes_ = &scene_.meshes;
      if (group.meshes.empty()) shapes.warn("the group has no triangles");
      group_index_[name] = static_cast<uint32_t>(scene_.groups.size());
      scene_.groups.push_back(std::move(group));
    }
  }

  void read_instance(const Node& n) {
    n.allow_keys({"type", "group", "transform"});
    const Node name = n.require("group");
    const auto it = group_index_.find(read_string(name));
    if (it == group_index_.end()) {
      std::string known;
      for (const auto& [key, index] : group_index_) known += (known.empty() ? "" : ", ") + key;
      name.fail("unknown group " + as_written(name.json()) +
                (known.empty() ? "; no groups are defined" : "; defined: " + printable(known)));
    }
    if (scene_.instances.size() >= kMaxInstances) {
      n.fail("more than " + std::to_string(kMaxInstances) + " instances");
    }
    if (auto refusal = instance_budget_.add(scene_, it->second)) n.fail(*refusal);
    Instance instance;
    instance.group = it->second;
    if (auto t = n.find("transform")) {
      const Transform transform = read_transform(*t);
      const double det = transform.determinant();
      if (!(std::fabs(det) > 0.0) || !std::isfinite(det))
        t->fail("the transform is not invertible (determinant " + std::to_string(det) + ")");
      if (!instance_budget_.placed_in_range(scene_, it->second, transform))
        t->fail(
            "the transform places the group's points beyond 1e17, the largest coordinate "
            "that the renderer handles");
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) instance.world_from_object[4 * r + c] = transform.at(r, c);
    }
    scene_.instances.push_back(instance);
  }

  void read_sphere(const Node& n) {
    n.allow_keys({"type", "center", "radius", "material", "transform"});
    Sphere s;
    s.center = read_point(n.require("center"));
    s.radius = read_length(n.require("radius"));
    s.material = material_ref(n.require("material"));
    if (auto t = n.find("transform")) transform_sphere(s, read_transform(*t), *t);
    scene_.spheres.push_back(s);
  }

  void read_quad(const Node& n, const std::string& origin) {
    n.allow_keys({"type", "corner", "edge1", "edge2", "material", "transform"});
    const Vec3 c = read_point(n.require("corner"));
    const Vec3 e1 = read_point(n.require("edge1"));
    const Vec3 e2 = read_point(n.require("edge2"));
    const uint32_t material = material_ref(n.require("material"));
    if (cross_length(e1, e2) == 0.0) {
      n.warn("the quad has zero area and is dropped");
      return;
    }
    // Both triangles' front faces, (v1-v0) x (v2-v0), point along edge1 x edge2. Texture
    // coordinates run from (0, 0) at the corner to (1, 1) at corner + edge1 + edge2.
    add_triangles(n, origin, {c, c + e1, c + e1 + e2, c + e2}, {0, 1, 2, 0, 2, 3}, material,
                  {{0.f, 0.f}, {1.f, 0.f}, {1.f, 1.f}, {0.f, 1.f}});
  }

  void read_triangle(const Node& n, const std::string& origin) {
    n.allow_keys({"type", "vertices", "material", "transform"});
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
    add_triangles(n, origin, {a, b, c}, {0, 1, 2}, material, {});
  }

  void add_triangles(const Node& n, const std::string& origin, std::vector<Vec3> positions,
                     std::vector<uint32_t> indices, uint32_t material, std::vector<Vec2> uvs) {
    TriangleMesh mesh;
    mesh.materials.assign(indices.size() / 3, material);
    mesh.positions = std::move(positions);
    mesh.indices = std::move(indices);
    mesh.uvs = std::move(uvs);
    mesh.origin = origin;
    if (auto t = n.find("transform")) transform_mesh(mesh, read_transform(*t), *t);
    meshes_->push_back(std::move(mesh));
  }

  void read_mesh(const Node& n) {
    n.allow_keys({"type", "file", "material", "transform"});
    const fs::path relative = mesh_path(n.require("file"));
    std::optional<uint32_t> material;
    if (auto m = n.find("material")) material = material_ref(*m);
    MeshFile loaded =
        is_ply_file(relative) ? load_ply(folder_, relative) : load_obj(folder_, relative);
    for (const fs::path& file : loaded.files) add_referenced(file);
    for (std::string& w : loaded.warnings) scene_.warnings.push_back(std::move(w));
    std::vector<uint32_t> remap;
    for (Material& m : loaded.materials)
      remap.push_back(material ? *material : add_material(std::move(m)));
    for (uint32_t& index : loaded.mesh.materials) index = remap.at(index);
    if (loaded.mesh.triangle_count() == 0) {
      n.warn("the mesh has no triangles");
      return;
    }
    if (auto t = n.find("transform")) transform_mesh(loaded.mesh, read_transform(*t), *t);
    if (split_meshes_ + loaded.object_starts.size() >= kMaxSplitMeshes) loaded.object_starts = {};
    if (!loaded.object_starts.empty()) split_meshes_ += loaded.object_starts.size() + 1;
    for (TriangleMesh& part : split_objects(std::move(loaded))) meshes_->push_back(std::move(part));
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

  Scene& scene_;
  const Context& context_;
  fs::path folder_;
  const SceneCheck& check_;
  SceneImages images_;
  std::map<std::string, uint32_t> material_index_;
  TextureReader textures_;
  std::vector<TriangleMesh>* meshes_ = &scene_.meshes;  // where shapes go: the world or a group
  size_t split_meshes_ = 0;  // meshes that OBJ objects became so far (kMaxSplitMeshes)
  std::map<std::string, uint32_t> group_index_;
  InstanceBudget instance_budget_;
};

}  // namespace

std::optional<FrameRange> load_scene_animation(const std::filesystem::path& file) {
  if (is_mitsuba_path(file)) return std::nullopt;
  // A glTF file's frames come from its animations' keys: the file is read.
  if (is_gltf_path(file)) return load_scene(file, {}, SceneImages::kCheckOnly).animation;
  const std::string name = file.string();
  const Json parsed = parse_json(read_text_file(file, kMaxSceneFileBytes, name), name);
  std::vector<std::string> warnings;
  const Context context{name, &warnings};
  const Node top(parsed, context, "");
  top.object();
  return read_animation(top);
}

namespace {

Scene load_scene_at(const fs::path& file, const SceneCheck& check, SceneImages images,
                    const GltfOptions& gltf, const fs::path& scene_root,
                    std::optional<int64_t> frame, double frame_offset) {
  const std::string name = file.string();
  if (is_gltf_path(file)) return load_gltf_scene(file, check, images, gltf, frame, frame_offset);
  if (is_mitsuba_path(file)) {
    check_frame(name, std::nullopt, frame);
    return load_mitsuba_scene(file, check, images, scene_root);
  }
  const Json parsed = parse_json(read_text_file(file, kMaxSceneFileBytes, name), name);
  Scene scene;
  scene.source = file;
  const Context context{name, &scene.warnings};
  const Node parsed_top(parsed, context, "");
  parsed_top.object();
  scene.animation = read_animation(parsed_top);
  check_frame(name, scene.animation, frame);
  if (scene.animation) scene.frame = frame ? *frame : scene.animation->first;
  const std::optional<Json> resolved = resolve_keyframes(
      parsed_top, scene.animation, double(scene.frame.value_or(0)) + frame_offset);
  const Node top(resolved ? *resolved : parsed, context, "");
  try {
    SceneReader(&scene, context, file.parent_path(), check, images, frame_offset).read(top);
  } catch (const SceneRefused&) {
    throw;
  } catch (const SceneError& e) {
    if (!resolved) throw;
    // A keyframed value may be wrong at this frame alone: say which.
    std::string when = "frame " + std::to_string(*scene.frame);
    if (frame_offset != 0.0) when += fmt::format(" {:+g}", frame_offset);
    throw SceneError(when + " of " + e.what());
  }
  return scene;
}

}  // namespace

Scene load_scene(const fs::path& file, const SceneCheck& check, SceneImages images,
                 const GltfOptions& gltf, const fs::path& scene_root,
                 std::optional<int64_t> frame) {
  Scene scene = load_scene_at(file, check, images, gltf, scene_root, frame, 0.0);
  if (!has_light(scene)) scene.warnings.push_back(file.string() + kNoLightWarning);
  return scene;
}

Scene load_scene_pose(const fs::path& file, const GltfOptions& gltf, const fs::path& scene_root,
                      std::optional<int64_t> frame, double frame_offset) {
  return load_scene_at(file, {}, SceneImages::kSkip, gltf, scene_root, frame, frame_offset);
}

}  // namespace rayfarm
