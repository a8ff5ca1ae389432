#include "renderer/surface_shading.h"

#include <cmath>
#include <variant>

#include "renderer/textures/texture_set.h"

namespace rayfarm {
namespace {

Vec3 orthogonal_unit(const Vec3& v, const Vec3& n) {
  const Vec3 o = v - n * dot(n, v);
  const float len = length(o);
  return len > 1e-6f && std::isfinite(len) ? o / len : Vec3(0.f);
}

/// The step of the height's finite differences: half a texel of an image, so that bilinear
/// filtering's slope is seen at its own scale; a small fraction of the unit square otherwise.
Vec2 height_step(const TextureSet& set, uint32_t texture) {
  if (const auto* image = std::get_if<ImageTexture>(&set.texture(texture))) {
    return {0.5f / float(image->image().width()), 0.5f / float(image->image().height())};
  }
  return {1e-3f, 1e-3f};
}

float height(const TextureSet& set, uint32_t texture, float u, float v) {
  const Vec4 t = set.eval(texture, u, v);
  const float h = (t.x + t.y + t.z) * (1.f / 3.f);
  return std::isfinite(h) ? h : 0.f;
}

}  // namespace

Frame tangent_aligned_frame(const Vec3& n, const Vec3& tangent) {
  Frame frame(n);
  const Vec3 s = orthogonal_unit(tangent, n);
  if (is_black(s)) return frame;
  frame.s = s;
  frame.t = cross(n, s);  // s x t = n, as Frame(n) has it
  return frame;
}

Vec3 apply_tangent_normal(const Vec3& ns, const TangentFrame& tf, const Vec3& m) {
  if (m.x == 0.f && m.y == 0.f && m.z > 0.f) return ns;
  // Without a known tangent, an arbitrary frame still gives the tilt its size.
  Vec3 t = orthogonal_unit(tf.tangent, ns);
  if (is_black(t)) t = Frame(ns).s;
  Vec3 b = cross(ns, t);
  if (dot(b, tf.bitangent) < 0.f) b = -b;
  const Vec3 out = t * m.x + b * m.y + ns * m.z;
  const float len = length(out);
  return len > 0.f && std::isfinite(len) ? out / len : ns;
}

Vec3 bumped_normal(const Vec3& ns, const TangentFrame& tf, float dh_du, float dh_dv) {
  const Vec3 du = tf.dpdu + ns * dh_du, dv = tf.dpdv + ns * dh_dv;
  const Vec3 c = cross(du, dv);
  const float len = length(c);
  if (!(len > 0.f) || !std::isfinite(len)) return ns;
  return dot(c, ns) < 0.f ? -(c / len) : c / len;
}

Frame shade_surface(const SceneData& data, const RayHit& rh, SurfaceHit& hit) {
  const uint8_t needs = data.surface_needs(hit.material);
  if ((needs & (kNeedsTangentFrame | kNeedsSurfaceMap)) == 0) return Frame(hit.ns);
  const TangentFrame tf = data.tangent_frame(rh, hit);
  if (needs & kNeedsSurfaceMap) {
    const Material& m = data.material(hit.material);
    const TextureSet& set = data.textures();
    Vec3 ns = hit.ns;
    if (m.normal_map) {
      const Vec4 t = set.eval(m.normal_map->texture, hit.uv.x, hit.uv.y);
      const float scale = m.normal_map->scale;
      const Vec3 local((2.f * t.x - 1.f) * scale, (2.f * t.y - 1.f) * scale, 2.f * t.z - 1.f);
      if (is_finite(local)) ns = apply_tangent_normal(hit.ns, tf, local);
    } else if (m.bump_map) {
      const uint32_t tex = m.bump_map->texture;
      const Vec2 step = height_step(set, tex);
      const float u = hit.uv.x, v = hit.uv.y, scale = m.bump_map->scale;
      const float dh_du = scale *
                          (height(set, tex, u + step.x, v) - height(set, tex, u - step.x, v)) /
                          (2.f * step.x);
      const float dh_dv = scale *
                          (height(set, tex, u, v + step.y) - height(set, tex, u, v - step.y)) /
                          (2.f * step.y);
      if (dh_du != 0.f || dh_dv != 0.f) ns = bumped_normal(hit.ns, tf, dh_du, dh_dv);
    }
    // A normal at or beyond the geometric horizon would shade the surface from inside; the
    // interpolated one stays then (unless the material keeps its mapped normal regardless).
    if ((needs & kShadingSided) || dot(ns, hit.n) > 1e-4f) hit.ns = ns;
  }
  return (needs & kNeedsTangentFrame) ? tangent_aligned_frame(hit.ns, tf.tangent) : Frame(hit.ns);
}

}  // namespace rayfarm
