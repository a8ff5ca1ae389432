// Mitsuba 3 shapes and emitters as rayfarm geometry and lights (docs/mitsuba.md, "Shapes",
// "Emitters").
#include <cmath>
#include <iterator>

#include "common/limits.h"
#include "common/scene/instances.h"
#include "common/scene/json_reader.h"
#include "common/scene/mitsuba_reader.h"
#include "common/scene/obj_loader.h"
#include "common/scene/ply_loader.h"
#include "common/scene/transform_reader.h"
#include "common/util/text.h"

namespace rayfarm::mitsuba {
namespace fs = std::filesystem;

namespace {

constexpr double kPi = 3.14159265358979323846;
/// Segments of a disk's polygon: its area is short of the disk's by (2 pi / n)^2 / 6 = 2.5e-5.
constexpr int kDiskSegments = 512;

Vec3 to_vec(const WideVec3& v) { return {float(v.x), float(v.y), float(v.z)}; }

/// Mitsuba gives a mesh without normals smooth ones: each vertex the angle-weighted mean of its
/// faces' normals.
void smooth_normals(TriangleMesh& mesh) {
  std::vector<WideVec3> sum(mesh.positions.size(), WideVec3{0, 0, 0});
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const uint32_t* idx = &mesh.indices[3 * t];
    const WideVec3 n =
        edge_cross(mesh.positions[idx[0]], mesh.positions[idx[1]], mesh.positions[idx[2]]);
    const double len = length(n);
    if (!(len > 0.0)) continue;
    for (int j = 0; j < 3; ++j) {
      const WideVec3 a = wide(mesh.positions[idx[(j + 1) % 3]]) - wide(mesh.positions[idx[j]]);
      const WideVec3 b = wide(mesh.positions[idx[(j + 2) % 3]]) - wide(mesh.positions[idx[j]]);
      const double la = length(a), lb = length(b);
      if (!(la > 0.0 && lb > 0.0)) continue;
      const double c = std::clamp((a.x * b.x + a.y * b.y + a.z * b.z) / (la * lb), -1.0, 1.0);
      const double w = std::acos(c) / len;
      WideVec3& s = sum[idx[j]];
      s = {s.x + n.x * w, s.y + n.y * w, s.z + n.z * w};
    }
  }
  mesh.normals.resize(mesh.positions.size());
  for (size_t i = 0; i < sum.size(); ++i) {
    const double len = length(sum[i]);
    mesh.normals[i] =
        len > 0.0 ? Vec3(float(sum[i].x / len), float(sum[i].y / len), float(sum[i].z / len))
                  : Vec3(0.f);
  }
}

void add_quad(TriangleMesh& m, const Vec3& o, const Vec3& du, const Vec3& dv, const Vec3& n) {
  const auto base = static_cast<uint32_t>(m.positions.size());
  m.positions.insert(m.positions.end(), {o, o + du, o + du + dv, o + dv});
  m.normals.insert(m.normals.end(), {n, n, n, n});
  m.uvs.insert(m.uvs.end(), {Vec2{0.f, 0.f}, Vec2{1.f, 0.f}, Vec2{1.f, 1.f}, Vec2{0.f, 1.f}});
  m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

TriangleMesh rectangle() {
  TriangleMesh m;
  add_quad(m, Vec3(-1.f, -1.f, 0.f), Vec3(2.f, 0.f, 0.f), Vec3(0.f, 2.f, 0.f), Vec3(0.f, 0.f, 1.f));
  return m;
}

/// Mitsuba's cube: [-1, 1]^3, each face its own four corners with flat normals, and its texture
/// coordinates laid out as Mitsuba lays them (corners in this order at (0, 1), (1, 1), (1, 0) and
/// (0, 0); triangles (0, 1, 2) and (3, 0, 2), wound to face outwards).
TriangleMesh cube() {
  struct Face {
    Vec3 n;
    Vec3 corners[4];
  };
  const Face faces[6] = {
      {{0, -1, 0}, {{1, -1, -1}, {1, -1, 1}, {-1, -1, 1}, {-1, -1, -1}}},
      {{0, 1, 0}, {{1, 1, -1}, {-1, 1, -1}, {-1, 1, 1}, {1, 1, 1}}},
      {{1, 0, 0}, {{1, -1, -1}, {1, 1, -1}, {1, 1, 1}, {1, -1, 1}}},
      {{0, 0, 1}, {{1, -1, 1}, {1, 1, 1}, {-1, 1, 1}, {-1, -1, 1}}},
      {{-1, 0, 0}, {{-1, -1, 1}, {-1, 1, 1}, {-1, 1, -1}, {-1, -1, -1}}},
      {{0, 0, -1}, {{1, 1, -1}, {1, -1, -1}, {-1, -1, -1}, {-1, 1, -1}}},
  };
  TriangleMesh m;
  for (const Face& f : faces) {
    const auto base = static_cast<uint32_t>(m.positions.size());
    m.positions.insert(m.positions.end(), std::begin(f.corners), std::end(f.corners));
    m.normals.insert(m.normals.end(), {f.n, f.n, f.n, f.n});
    m.uvs.insert(m.uvs.end(), {Vec2{0.f, 1.f}, Vec2{1.f, 1.f}, Vec2{1.f, 0.f}, Vec2{0.f, 0.f}});
    m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base + 3, base, base + 2});
  }
  return m;
}

TriangleMesh disk() {
  TriangleMesh m;
  m.positions.push_back(Vec3(0.f));
  m.uvs.push_back(Vec2{0.5f, 0.5f});
  for (int i = 0; i < kDiskSegments; ++i) {
    const double phi = 2.0 * kPi * i / kDiskSegments;
    const float x = float(std::cos(phi)), y = float(std::sin(phi));
    m.positions.push_back(Vec3(x, y, 0.f));
    m.uvs.push_back(Vec2{0.5f * (x + 1.f), 0.5f * (y + 1.f)});
    const auto next = static_cast<uint32_t>(1 + (i + 1) % kDiskSegments);
    m.indices.insert(m.indices.end(), {0u, static_cast<uint32_t>(1 + i), next});
  }
  m.normals.assign(m.positions.size(), Vec3(0.f, 0.f, 1.f));
  return m;
}

void flip(TriangleMesh& m) {
  for (size_t t = 0; t < m.triangle_count(); ++t)
    std::swap(m.indices[3 * t + 1], m.indices[3 * t + 2]);
  for (Vec3& n : m.normals) n = -1.f * n;
}

/// The material of a shape: its BSDF, and its area emitter's radiance when it has one.
uint32_t shape_material(Context& ctx, Props& p, UvKind uv, bool in_group) {
  const auto bsdfs = p.plugins("bsdf");
  if (bsdfs.size() > 1) p.element().fail("a shape takes one <bsdf>");
  uint32_t material = material_of(ctx, bsdfs.empty() ? nullptr : bsdfs[0], uv);
  const auto emitters = p.plugins("emitter");
  if (emitters.size() > 1) p.element().fail("a shape takes one <emitter>");
  if (emitters.empty()) return material;
  const XmlElement& e = *emitters[0];
  if (type_of(e) != "area") e.fail("a shape's emitter must be of type area");
  if (in_group) e.fail("emitters inside a shapegroup are not supported");
  Props ep(e, ctx);
  Material m = ctx.scene.materials[material];
  m.emission = textured_rgb(ctx, ep.colour("radiance", Vec3(1.f), SpectrumRole::emission), uv);
  ep.finish();
  if (m.has_alpha()) e.fail("an emitter cannot have cut-outs (its BSDF is a mask)");
  m.name += " (emitting)";
  material = static_cast<uint32_t>(ctx.scene.materials.size());
  ctx.scene.materials.push_back(std::move(m));
  return material;
}

}  // namespace

void read_shape(Context& ctx, const XmlElement& shape, std::vector<TriangleMesh>& meshes,
                bool in_group, std::map<const XmlElement*, uint32_t>& groups) {
  Props p(shape, ctx);
  const std::string type = type_of(shape);
  At at(shape, ctx.scene, "to_world");
  if (type == "shapegroup") {
    if (in_group) shape.fail("a shapegroup inside a shapegroup is not supported");
    MeshGroup group;
    const std::string* id = shape.find("id");
    group.name = id != nullptr ? *id : shape.where();
    std::vector<Sphere> spheres;
    ctx.group_spheres_open = &spheres;
    for (const XmlElement* s : p.plugins("shape")) read_shape(ctx, *s, group.meshes, true, groups);
    ctx.group_spheres_open = nullptr;
    p.finish();
    const auto index = static_cast<uint32_t>(ctx.scene.groups.size());
    groups[&shape] = index;
    if (!spheres.empty()) ctx.group_spheres[index] = std::move(spheres);
    ctx.scene.groups.push_back(std::move(group));
    return;
  }
  if (type == "instance") {
    if (in_group) shape.fail("an instance inside a shapegroup is not supported");
    const auto refs = p.plugins("shape");
    if (refs.size() != 1 || type_of(*refs[0]) != "shapegroup")
      shape.fail("an instance names one shapegroup with <ref id=\"...\"/>");
    auto it = groups.find(refs[0]);
    if (it == groups.end()) shape.fail("the shapegroup must come before its instances");
    const Transform t = p.transform("to_world");
    p.finish();
    if (ctx.scene.instances.size() >= kMaxInstances) shape.fail("too many instances");
    // The group's spheres, placed as spheres of the scene (the instance must keep them round).
    if (auto spheres = ctx.group_spheres.find(it->second); spheres != ctx.group_spheres.end()) {
      ctx.instanced_spheres += spheres->second.size();
      if (ctx.instanced_spheres > kMaxInstances)
        shape.fail("instances place more than 2^20 spheres");
      for (Sphere s : spheres->second) {
        transform_sphere(s, t, at.node);
        ctx.scene.spheres.push_back(s);
      }
    }
    if (ctx.scene.groups[it->second].meshes.empty()) return;  // spheres only
    Instance inst;
    inst.group = it->second;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) inst.world_from_object[4 * r + c] = t.at(r, c);
    }
    ctx.scene.instances.push_back(inst);
    return;
  }
  if (type == "sphere") {
    Sphere s;
    const Transform t = p.transform("to_world");
    s.center = to_vec(p.point("center").value_or(WideVec3{0, 0, 0}));
    s.radius = static_cast<float>(p.number("radius", 1.0));
    if (!(s.radius > 0.f)) shape.fail("a sphere's radius must be positive");
    if (p.boolean("flip_normals", false)) shape.fail("flip_normals on a sphere is not supported");
    s.material = shape_material(ctx, p, UvKind::kNative, in_group);
    p.finish();
    transform_sphere(s, t, at.node);
    (in_group ? *ctx.group_spheres_open : ctx.scene.spheres).push_back(s);
    return;
  }
  TriangleMesh mesh;
  UvKind uv = UvKind::kNative;
  if (type == "obj" || type == "ply") {
    const XmlElement* file = p.find("filename");
    if (file == nullptr) shape.fail("a mesh needs a filename");
    const fs::path rel = resolve_mitsuba_file(ctx.files, *file, value_of(*file));
    MeshFile mf = type == "ply" ? load_ply(ctx.files.scene_dir, rel)
                                : load_obj(ctx.files.scene_dir, rel, false);
    for (const fs::path& f : mf.files) {
      if (std::find(ctx.files.read.begin(), ctx.files.read.end(), f) == ctx.files.read.end())
        ctx.files.read.push_back(f);
    }
    for (std::string& w : mf.warnings) ctx.scene.warnings.push_back(std::move(w));
    mesh = std::move(mf.mesh);
    mesh.origin = rel.generic_string();
    // Mitsuba flips an OBJ's v by default, not a PLY's.
    if (p.boolean("flip_tex_coords", type == "obj")) uv = UvKind::kMeshFile;
    if (p.boolean("face_normals", false))
      mesh.normals.clear();
    else if (mesh.normals.empty())
      smooth_normals(mesh);
  } else if (type == "rectangle") {
    mesh = rectangle();
  } else if (type == "cube") {
    mesh = cube();
  } else if (type == "disk") {
    mesh = disk();
  } else {
    shape.fail("the shape \"" + printable(type, 40) +
               "\" is not supported (docs/mitsuba.md lists the shapes rayfarm reads)");
  }
  if (mesh.origin.empty()) mesh.origin = shape.where();
  const Transform t = p.transform("to_world");
  if (p.boolean("flip_normals", false)) flip(mesh);
  const uint32_t material = shape_material(ctx, p, uv, in_group);
  p.finish();
  mesh.materials.assign(mesh.triangle_count(), material);
  transform_mesh(mesh, t, at.node);
  if (mesh.triangle_count() == 0) {
    ctx.warn_once("empty:" + mesh.origin, shape, "the shape has no triangles");
    return;
  }
  meshes.push_back(std::move(mesh));
}

}  // namespace rayfarm::mitsuba
