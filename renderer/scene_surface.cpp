// What surfaces need beyond their BSDF: tangent frames (normal and bump maps, anisotropic BSDFs)
// and opacity cut-outs, both decided per material so that a scene without them pays nothing.
#include <bit>
#include <cmath>
#include <cstdint>
#include <variant>

#include "renderer/scene_data.h"

#include "common/scene/motion.h"
#include "renderer/motion_blend.h"
#include "renderer/textures/texture_lookup.h"

namespace rayfarm {
namespace {

/// Whether the BSDF of `kind` depends on the direction of the tangent.
bool anisotropic(const MaterialKind& kind) {
  const auto differ = [](const TexturedFloat& u, const TexturedFloat& v) {
    return u.is_textured() || v.is_textured() || u.value != v.value;
  };
  if (const auto* c = std::get_if<RoughConductorMaterial>(&kind))
    return differ(c->alpha_u, c->alpha_v);
  if (const auto* d = std::get_if<RoughDielectricMaterial>(&kind))
    return differ(d->alpha_u, d->alpha_v);
  return false;
}

bool keep_covered(const void* context, uint32_t geom, uint32_t prim, float u, float v,
                  const Vec3& p, float time) {
  return static_cast<const SceneData*>(context)->covered(geom, prim, u, v, p, time);
}

bool keep_covered_in_group(const void* context, uint32_t geom, uint32_t prim, float u, float v,
                           const Vec3& p, float /*time*/) {
  const auto* g = static_cast<const SceneData::GroupFilter*>(context);
  return g->data->covered_in_group(g->group, geom, prim, u, v, p);
}

/// The texture coordinates of barycentrics (u, v) on triangle `prim` of `mesh`: the
/// barycentrics themselves when the mesh has none.
Vec2 triangle_uv(const TriangleMesh& mesh, uint32_t prim, float u, float v) {
  if (mesh.uvs.empty()) return {u, v};
  const uint32_t* idx = &mesh.indices[3 * size_t(prim)];
  return mesh.uvs[idx[0]] * (1.f - u - v) + mesh.uvs[idx[1]] * u + mesh.uvs[idx[2]] * v;
}

}  // namespace

void SceneData::build_surface(std::vector<Bvh::Mesh>& meshes, const Bvh::HitFilter*& sphere_filter,
                              std::vector<std::vector<Bvh::Mesh>>& groups) {
  std::vector<uint8_t> cut_out;
  for (const Material& m : scene_.materials) {
    uint8_t needs = 0;
    if (anisotropic(m.kind)) needs |= kNeedsTangentFrame;
    if (m.has_surface_map()) needs |= kNeedsSurfaceMap;
    if (m.one_sided) needs |= kOneSided;
    if (m.one_sided && m.shading_sided) needs |= kShadingSided;
    if (m.normal_map) {
      const TextureDesc& t = scene_.textures.at(m.normal_map->texture);
      if (t.kind == TextureDesc::Kind::kImage && t.options.origin == UvOrigin::top_left)
        needs |= kFlipBitangent;
    }
    surface_needs_.push_back(needs);
    uses_surface_ = uses_surface_ || needs != 0;
    cut_out.push_back(m.has_alpha());
  }
  cut_out_filter_ = {keep_covered, this};
  for (size_t i = 0; i < scene_.meshes.size(); ++i) {
    for (const uint32_t material : scene_.meshes[i].materials) {
      if (cut_out[material]) {
        meshes[i].filter = &cut_out_filter_;
        break;
      }
    }
  }
  for (const Sphere& s : scene_.spheres) {
    if (cut_out[s.material]) sphere_filter = &cut_out_filter_;
  }
  // Sized once: Embree keeps the contexts' addresses.
  group_filter_contexts_.resize(scene_.groups.size());
  group_filters_.resize(scene_.groups.size());
  for (uint32_t g = 0; g < scene_.groups.size(); ++g) {
    group_filter_contexts_[g] = {this, g};
    group_filters_[g] = {keep_covered_in_group, &group_filter_contexts_[g]};
    for (size_t i = 0; i < scene_.groups[g].meshes.size(); ++i) {
      for (const uint32_t material : scene_.groups[g].meshes[i].materials) {
        if (cut_out[material]) {
          groups[g][i].filter = &group_filters_[g];
          break;
        }
      }
    }
  }
}

namespace {

uint64_t mix64(uint64_t h) {  // a 64-bit finaliser: every input bit moves every output bit
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdULL;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ULL;
  return h ^ (h >> 33);
}

/// A number in [0, 1) that only the hit decides: its point and its triangle.
float coverage_number(const Vec3& p, uint32_t prim) {
  uint64_t h = mix64(std::bit_cast<uint32_t>(p.x) ^ (uint64_t{prim} << 32));
  h = mix64(h ^ std::bit_cast<uint32_t>(p.y));
  h = mix64(h ^ (uint64_t{std::bit_cast<uint32_t>(p.z)} << 17));
  return static_cast<float>(h >> 40) * 0x1p-24f;
}

}  // namespace

bool SceneData::opaque_at(uint32_t material, const Vec2& uv, const Vec3& p, uint32_t prim) const {
  const Material& m = scene_.materials[material];
  if (!m.has_alpha()) return true;
  const float alpha = TextureLookup(&textures_, uv).number(m.alpha);
  if (m.alpha_blend) return coverage_number(p, prim) < alpha;
  return !(alpha < m.alpha_cutoff);
}

bool SceneData::covered_in_group(uint32_t group, uint32_t geom, uint32_t prim, float u, float v,
                                 const Vec3& p) const {
  const size_t mesh = group_first_mesh_[group] + geom;
  const uint32_t material = group_triangles_[group_mesh_offset_[mesh] + prim].material;
  return opaque_at(material, triangle_uv(scene_.groups[group].meshes[geom], prim, u, v), p, prim);
}

bool SceneData::covered(uint32_t geom, uint32_t prim, float u, float v, const Vec3& p,
                        float time) const {
  uint32_t material;
  Vec2 uv;
  if (geom == kSphereGeometry) {
    const auto look_up = [&](const Sphere& sphere) {
      material = sphere.material;
      uv = sphere_uv(sphere, unit_or_zero(p - sphere.center));
    };
    if (moves_ && sphere_motion_[prim] >= 0) {
      Sphere posed;
      look_up(sphere_at(prim, time, posed));
    } else {
      look_up(scene_.spheres[prim]);
    }
  } else {
    material = triangles_[mesh_offset_[geom] + prim].material;
    uv = triangle_uv(scene_.meshes[geom], prim, u, v);
  }
  return opaque_at(material, uv, p, prim);
}

TangentFrame SceneData::tangent_frame(const RayHit& hit, const SurfaceHit& s) const {
  TangentFrame f;
  if (hit.geom == kSphereGeometry) {
    Sphere posed;  // tangent frames are needed only by some materials: the scratch is cheap here
    const Sphere& sphere = sphere_at(hit.prim, s.time, posed);
    // p = r (sin t cos f, sin t sin f, cos t) in the sphere's frame, u = f / 2pi, v = t / pi.
    const float x = dot(s.n, sphere.axis_x), y = dot(s.n, sphere.axis_y),
                z = dot(s.n, sphere.axis_z);
    const float sin_theta = std::sqrt(x * x + y * y);
    if (sin_theta > 1e-6f) {
      const float r = sphere.radius;
      f.dpdu = (sphere.axis_x * -y + sphere.axis_y * x) * (2.f * kPi * r);
      f.dpdv = (sphere.axis_x * (z * x / sin_theta) + sphere.axis_y * (z * y / sin_theta) -
                sphere.axis_z * sin_theta) *
               (kPi * r);
    }
  } else {
    // An instanced hit's frame is found in object space, then placed: vectors by the instance's
    // 3x3 part, as place_mesh places a world copy's positions and tangents.
    InstanceInfo posed_instance;
    const InstanceInfo* in = hit.inst == kNoInstance ? nullptr
                             : moves_ ? &instance_at(hit.inst, s.time, posed_instance)
                                      : &instances_[hit.inst];
    const TriangleInfo* tri;
    const TriangleMesh* object;
    TriangleInfo posed_triangle;
    // A moving mesh's own tangents are those of its frame pose: its frame follows the posed
    // triangle's texture coordinates instead.
    bool own_tangents = true;
    if (in != nullptr) {
      const size_t mesh = group_first_mesh_[in->group] + hit.geom;
      tri = &group_triangles_[group_mesh_offset_[mesh] + hit.prim];
      object = &scene_.groups[in->group].meshes[hit.geom];
    } else {
      tri = &triangles_[mesh_offset_[hit.geom] + hit.prim];
      object = &scene_.meshes[hit.geom];
      if (moves_ && mesh_motion_[hit.geom] >= 0) {
        const auto& poses = scene_.motion->meshes[size_t(mesh_motion_[hit.geom])].positions;
        const uint32_t* idx = &object->indices[3 * size_t(hit.prim)];
        const PoseBlend b = pose_blend(poses_, s.time);
        const auto at = [&](uint32_t v) { return blend(poses[b.i][v], poses[b.i + 1][v], b.f); };
        posed_triangle = *tri;
        posed_triangle.v0 = at(idx[0]);
        posed_triangle.e1 = at(idx[1]) - posed_triangle.v0;
        posed_triangle.e2 = at(idx[2]) - posed_triangle.v0;
        tri = &posed_triangle;
        own_tangents = false;
      }
    }
    const TriangleMesh& mesh = *object;
    const auto place = [in](const Vec3& v) {
      if (in == nullptr) return v;
      const auto& m = in->m;
      return Vec3(m[0] * v.x + m[1] * v.y + m[2] * v.z, m[4] * v.x + m[5] * v.y + m[6] * v.z,
                  m[8] * v.x + m[9] * v.y + m[10] * v.z);
    };
    const uint32_t* idx = &mesh.indices[3 * size_t(hit.prim)];
    // p = v0 + b1 e1 + b2 e2; with texture coordinates, (e1 e2) = (dpdu dpdv) (duv1 duv2).
    f.dpdu = tri->e1;
    f.dpdv = tri->e2;
    if (!mesh.uvs.empty()) {
      const Vec2 d1 = mesh.uvs[idx[1]] - mesh.uvs[idx[0]], d2 = mesh.uvs[idx[2]] - mesh.uvs[idx[0]];
      const float det = d1.x * d2.y - d2.x * d1.y;
      if (std::fabs(det) > 1e-20f) {
        const float inv = 1.f / det;
        f.dpdu = (tri->e1 * d2.y - tri->e2 * d1.y) * inv;
        f.dpdv = (tri->e2 * d1.x - tri->e1 * d2.x) * inv;
      } else {
        f.dpdu = f.dpdv = Vec3(0.f);
      }
    }
    f.dpdu = place(f.dpdu);
    f.dpdv = place(f.dpdv);
    if (own_tangents && !mesh.tangents.empty()) {
      const float b0 = 1.f - hit.u - hit.v;
      const Vec4 &t0 = mesh.tangents[idx[0]], &t1 = mesh.tangents[idx[1]],
                 &t2 = mesh.tangents[idx[2]];
      // Each placed tangent is made unit before interpolating, as place_mesh stores them.
      const auto vertex = [&](const Vec4& t) {
        const Vec3 v(t.x, t.y, t.z);
        return in == nullptr ? v : unit_or_zero(place(v));
      };
      const Vec3 t = unit_or_zero(vertex(t0) * b0 + vertex(t1) * hit.u + vertex(t2) * hit.v);
      if (!is_black(t)) {
        // A mirror keeps the tangent and turns the bitangent: the handedness flips with it.
        const float sign = (t0.w < 0.f ? -1.f : 1.f) * (in != nullptr ? in->handedness : 1.f);
        f.tangent = t;
        f.bitangent = unit_or_zero(cross(s.ns, t) * sign);
        return f;
      }
    }
  }
  f.tangent = unit_or_zero(f.dpdu);
  // The image's up is +v for images whose origin is at the bottom, -v for those at the top.
  const bool flip = (surface_needs_[s.material] & kFlipBitangent) != 0;
  f.bitangent = unit_or_zero(flip ? -f.dpdv : f.dpdv);
  return f;
}

Vec3 SceneData::vertex_colour(const RayHit& hit) const {
  if (hit.geom == kSphereGeometry) return Vec3(1.f);
  const TriangleMesh& mesh = hit.inst != kNoInstance
                                 ? scene_.groups[instances_[hit.inst].group].meshes[hit.geom]
                                 : scene_.meshes[hit.geom];
  if (mesh.colours.empty()) return Vec3(1.f);
  const uint32_t* idx = &mesh.indices[3 * size_t(hit.prim)];
  // Barycentrics may stray a rounding below zero: no colour channel goes negative.
  return max(mesh.colours[idx[0]] * (1.f - hit.u - hit.v) + mesh.colours[idx[1]] * hit.u +
                 mesh.colours[idx[2]] * hit.v,
             Vec3(0.f));
}

}  // namespace rayfarm
