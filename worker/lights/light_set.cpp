#include "worker/lights/light_set.h"

#include <algorithm>
#include <cmath>

namespace rayfarm {
namespace {

Vec3 sample_uniform_sphere(float u1, float u2) {
  const float z = 1.f - 2.f * u1;
  const float r = std::sqrt(std::max(0.f, 1.f - z * z));
  const float phi = 2.f * kPi * u2;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

}  // namespace

Vec3 LightSet::emitted(const Material& m, const Vec3& n, const Vec3& w) {
  if (!m.is_emissive()) return Vec3(0.f);
  return (m.two_sided || dot(n, w) > 0.f) ? m.emission : Vec3(0.f);
}

LightSet::LightSet(SceneData& data) : data_(&data) {
  const Scene& scene = data.scene();
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const TriangleMesh& mesh = scene.meshes[m];
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      const Material& mat = scene.materials[mesh.materials[t]];
      if (!mat.is_emissive()) continue;
      const Vec3& a = mesh.positions[mesh.indices[3 * t]];
      const Vec3& b = mesh.positions[mesh.indices[3 * t + 1]];
      const Vec3& c = mesh.positions[mesh.indices[3 * t + 2]];
      const double area = triangle_area(a, b, c);
      Vec3 n;
      // An emitter that cannot be sampled keeps light index -1: BSDF rays then count it fully.
      if (!(area > 0.0) || area > 3e38 || !triangle_normal(a, b, c, n)) continue;
      const double sides = mat.two_sided ? 2.0 : 1.0;
      lights_.push_back({Kind::kTriangle, m, t, static_cast<float>(area), n,
                         double(luminance(mat.emission)) * area * kPi * sides});
    }
  }
  for (uint32_t s = 0; s < scene.spheres.size(); ++s) {
    const Material& mat = scene.materials[scene.spheres[s].material];
    if (!mat.is_emissive()) continue;
    const double r = scene.spheres[s].radius;
    const double area = 4.0 * kPi * r * r;
    if (!(area > 0.0) || area > 3e38) continue;
    const double sides = mat.two_sided ? 2.0 : 1.0;
    lights_.push_back({Kind::kSphere, kSphereGeometry, s, static_cast<float>(area), Vec3(),
                       double(luminance(mat.emission)) * area * kPi * sides});
  }
  for (uint32_t i = 0; i < scene.point_lights.size(); ++i) {
    const double power = 4.0 * kPi * double(luminance(scene.point_lights[i].intensity));
    if (!(power > 0.0)) continue;
    lights_.push_back({Kind::kPoint, 0, i, 0.f, Vec3(), power});
    ++point_count_;
  }
  // Emitters whose luminance is zero (e.g. pure blue below rounding) still get a small share.
  double total = 0.0;
  for (const Light& l : lights_) total += std::max(l.power, 1e-30);
  double running = 0.0;
  for (size_t i = 0; i < lights_.size(); ++i) {
    const Light& l = lights_[i];
    const double share = std::max(l.power, 1e-30);
    running += share;
    cdf_.push_back(static_cast<float>(running / total));
    if (l.kind != Kind::kPoint) data.set_light_index(l.geom, l.prim, static_cast<int32_t>(i));
  }
  if (!cdf_.empty()) cdf_.back() = 1.f;
}

float LightSet::selection_probability(int32_t light) const {
  if (light < 0) return 0.f;
  // The interval sample() maps to this light; for a light of negligible power the rounded cdf
  // may give it none, and then it is never chosen.
  const float lo = light == 0 ? 0.f : cdf_[light - 1];
  return cdf_[light] - lo;
}

bool LightSet::sample(const Vec3& ref, float u_select, float u1, float u2, LightSample& out) const {
  if (lights_.empty()) return false;
  int32_t index = 0;
  if (cdf_.size() > 1) {
    const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), u_select);
    index = static_cast<int32_t>(std::min<size_t>(it - cdf_.begin(), cdf_.size() - 1));
  }
  const float p_select = selection_probability(index);
  if (!(p_select > 0.f)) return false;
  const Light& light = lights_[index];
  const Scene& scene = data_->scene();

  if (light.kind == Kind::kPoint) {
    const PointLight& pl = scene.point_lights[light.prim];
    const Vec3 d = pl.position - ref;
    const float dist2 = dot(d, d);
    if (!(dist2 > 0.f)) return false;
    out.wi = d / std::sqrt(dist2);
    out.radiance = pl.intensity / dist2;
    out.target = pl.position;
    out.pdf = p_select;
    out.delta = true;
    return true;
  }

  Vec3 p, n;
  float p_error = 0.f;
  uint32_t material = 0;
  if (light.kind == Kind::kTriangle) {
    const TriangleMesh& mesh = scene.meshes[light.geom];
    const uint32_t* idx = &mesh.indices[3 * size_t{light.prim}];
    const Vec3& v0 = mesh.positions[idx[0]];
    const Vec3& v1 = mesh.positions[idx[1]];
    const Vec3& v2 = mesh.positions[idx[2]];
    // Uniform point on the triangle.
    const float su = std::sqrt(u1);
    const float b0 = 1.f - su, b1 = u2 * su, b2 = 1.f - b0 - b1;
    p = v0 * b0 + v1 * b1 + v2 * b2;
    p_error = triangle_point_error(v0, v1, v2);
    n = light.n;
    material = mesh.materials[light.prim];
  } else {
    const Sphere& s = scene.spheres[light.prim];
    n = sample_uniform_sphere(u1, u2);
    p = s.center + n * s.radius;
    p_error = sphere_point_error(s.center, s.radius);
    material = s.material;
  }
  // Distances in double: beyond ~1e19 their squares overflow a float, and the light would
  // silently never be sampled.
  const double dx = double(p.x) - ref.x, dy = double(p.y) - ref.y, dz = double(p.z) - ref.z;
  const double dist2 = dx * dx + dy * dy + dz * dz;
  if (!(dist2 > 0.0)) return false;
  const double dist = std::sqrt(dist2);
  out.wi = Vec3(static_cast<float>(dx / dist), static_cast<float>(dy / dist),
                static_cast<float>(dz / dist));
  const float cos_light = std::fabs(dot(n, out.wi));
  if (!(cos_light > 0.f)) return false;
  out.radiance = emitted(data_->material(material), n, -out.wi);
  if (is_black(out.radiance)) return false;
  out.pdf = static_cast<float>(p_select * dist2 / (double(cos_light) * light.area));
  out.target = offset_ray_origin(p, p_error, dot(n, out.wi) < 0.f ? n : -n);
  out.delta = false;
  return std::isfinite(out.pdf) && out.pdf > 0.f;
}

float LightSet::pdf(int32_t light, const Vec3& ref, const Vec3& p, const Vec3& n) const {
  if (light < 0) return 0.f;
  const Light& l = lights_[light];
  const double dx = double(p.x) - ref.x, dy = double(p.y) - ref.y, dz = double(p.z) - ref.z;
  const double dist2 = dx * dx + dy * dy + dz * dz;
  if (!(dist2 > 0.0)) return 0.f;
  const double cos_light = std::fabs(n.x * dx + n.y * dy + n.z * dz) / std::sqrt(dist2);
  if (!(cos_light > 0.0)) return 0.f;
  return static_cast<float>(selection_probability(light) * dist2 / (cos_light * l.area));
}

}  // namespace rayfarm
