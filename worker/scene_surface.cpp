// What surfaces need beyond their BSDF: tangent frames (normal and bump maps, anisotropic BSDFs)
// and opacity cut-outs, both decided per material so that a scene without them pays nothing.
#include <cmath>
#include <variant>

#include "worker/scene_data.h"
#include "worker/textures/texture_lookup.h"

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
                  const Vec3& p) {
  return static_cast<const SceneData*>(context)->covered(geom, prim, u, v, p);
}

Vec3 unit_or_zero(const Vec3& v) {
  const float len = length(v);
  return len > 0.f && std::isfinite(len) ? v / len : Vec3(0.f);
}

}  // namespace

void SceneData::build_surface(std::vector<Bvh::Mesh>& meshes,
                              const Bvh::HitFilter*& sphere_filter) {
  std::vector<uint8_t> cut_out;
  for (const Material& m : scene_.materials) {
    uint8_t needs = 0;
    if (anisotropic(m.kind)) needs |= kNeedsTangentFrame;
    if (m.has_surface_map()) needs |= kNeedsSurfaceMap;
    if (m.one_sided) needs |= kOneSided;
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
}

bool SceneData::covered(uint32_t geom, uint32_t prim, float u, float v, const Vec3& p) const {
  uint32_t material;
  Vec2 uv;
  if (geom == kSphereGeometry) {
    const Sphere& sphere = scene_.spheres[prim];
    material = sphere.material;
    uv = sphere_uv(sphere, unit_or_zero(p - sphere.center));
  } else {
    material = triangles_[mesh_offset_[geom] + prim].material;
    const TriangleMesh& mesh = scene_.meshes[geom];
    uv = {u, v};
    if (!mesh.uvs.empty()) {
      const uint32_t* idx = &mesh.indices[3 * size_t(prim)];
      uv = mesh.uvs[idx[0]] * (1.f - u - v) + mesh.uvs[idx[1]] * u + mesh.uvs[idx[2]] * v;
    }
  }
  const Material& m = scene_.materials[material];
  if (!m.has_alpha()) return true;
  return !(TextureLookup(&textures_, uv).number(m.alpha) < m.alpha_cutoff);
}

TangentFrame SceneData::tangent_frame(const RayHit& hit, const SurfaceHit& s) const {
  TangentFrame f;
  if (hit.geom == kSphereGeometry) {
    const Sphere& sphere = scene_.spheres[hit.prim];
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
    const TriangleInfo& tri = triangles_[mesh_offset_[hit.geom] + hit.prim];
    const TriangleMesh& mesh = scene_.meshes[hit.geom];
    const uint32_t* idx = &mesh.indices[3 * size_t(hit.prim)];
    // p = v0 + b1 e1 + b2 e2; with texture coordinates, (e1 e2) = (dpdu dpdv) (duv1 duv2).
    f.dpdu = tri.e1;
    f.dpdv = tri.e2;
    if (!mesh.uvs.empty()) {
      const Vec2 d1 = mesh.uvs[idx[1]] - mesh.uvs[idx[0]], d2 = mesh.uvs[idx[2]] - mesh.uvs[idx[0]];
      const float det = d1.x * d2.y - d2.x * d1.y;
      if (std::fabs(det) > 1e-20f) {
        const float inv = 1.f / det;
        f.dpdu = (tri.e1 * d2.y - tri.e2 * d1.y) * inv;
        f.dpdv = (tri.e2 * d1.x - tri.e1 * d2.x) * inv;
      } else {
        f.dpdu = f.dpdv = Vec3(0.f);
      }
    }
    if (!mesh.tangents.empty()) {
      const float b0 = 1.f - hit.u - hit.v;
      const Vec4 &t0 = mesh.tangents[idx[0]], &t1 = mesh.tangents[idx[1]],
                 &t2 = mesh.tangents[idx[2]];
      const Vec3 t = unit_or_zero(Vec3(t0.x, t0.y, t0.z) * b0 + Vec3(t1.x, t1.y, t1.z) * hit.u +
                                  Vec3(t2.x, t2.y, t2.z) * hit.v);
      if (!is_black(t)) {
        f.tangent = t;
        f.bitangent = unit_or_zero(cross(s.ns, t) * (t0.w < 0.f ? -1.f : 1.f));
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

}  // namespace rayfarm
