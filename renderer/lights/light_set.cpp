#include "renderer/lights/light_set.h"

#include <algorithm>
#include <cmath>

#include "common/math/wide.h"
#include "common/scene/instances.h"

namespace rayfarm {

namespace {

/// Radius of a sphere around the centre of the geometry's bounding box that holds all of it;
/// 1 for a scene without geometry (lights at infinity then still get a power).
double scene_radius(const Scene& scene) {
  // Instances count by their placed groups' boxes: the lights' power follows the whole scene.
  WideVec3 lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
  extend_bounds(scene, lo, hi);
  if (!(hi.x >= lo.x)) return 1.0;
  const double dx = hi.x - lo.x, dy = hi.y - lo.y, dz = hi.z - lo.z;
  const double r = 0.5 * std::sqrt(dx * dx + dy * dy + dz * dz);
  return r > 0.0 && std::isfinite(r) ? r : 1.0;
}

}  // namespace

LightSet::LightSet(SceneData& data, LightChoice choice) {
  const Scene& scene = data.scene();
  // Textured emission: its power from the texture's mean, computed once per material.
  const EmissionFootprints footprints(scene, data.textures());
  EmissionTextures emission{&data.textures(), {}, &footprints};
  for (const Material& m : scene.materials) {
    Vec3 mean = m.emission.value;
    if (m.emission.is_textured()) {
      const Vec4 t = data.textures().mean(static_cast<uint32_t>(m.emission.texture));
      mean = mean * Vec3(std::max(t.x, 0.f), std::max(t.y, 0.f), std::max(t.z, 0.f));
      // Any emission at all keeps a share of the light selection.
      if (!(luminance(mean) > 0.f)) mean = m.emission.value * 1e-6f;
    }
    emission.mean_radiance.push_back(mean);
  }
  // Area lights register their primitive, so that a BSDF ray hitting it finds its light index.
  const auto add_area = [&](const auto& light) {
    data.set_light_index(light.geom(), light.prim(), static_cast<int32_t>(lights_.size()));
    lights_.emplace_back(light);
    ++area_count_;
  };
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const TriangleMesh& mesh = scene.meshes[m];
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      // A textured emitter is a textured light or none (its black triangles), never a plain one.
      if (scene.materials[mesh.materials[t]].emission.is_textured()) {
        if (auto light = TexturedTriangleLight::make(scene, m, t, emission)) add_area(*light);
      } else if (auto plain = TriangleLight::make(scene, m, t, &emission)) {
        add_area(*plain);
      }
    }
  }
  for (uint32_t s = 0; s < scene.spheres.size(); ++s) {
    if (auto light = TexturedSphereLight::make(scene, s, emission)) {
      add_area(*light);
    } else if (auto plain = SphereLight::make(scene, s, &emission)) {
      add_area(*plain);
    }
  }
  for (uint32_t i = 0; i < scene.point_lights.size(); ++i) {
    if (auto light = DeltaPointLight::make(scene, i)) {
      lights_.emplace_back(*light);
      ++point_count_;
    }
  }
  for (uint32_t i = 0; i < scene.spot_lights.size(); ++i) {
    // A spot with an image is an image spot or none, never a plain one.
    if (scene.spot_lights[i].image) {
      if (auto light = ImageSpotLight::make(scene, i, &data.textures())) {
        lights_.emplace_back(*light);
        ++spot_count_;
      }
    } else if (auto light = DeltaSpotLight::make(scene, i)) {
      lights_.emplace_back(*light);
      ++spot_count_;
    }
  }
  const double radius = scene_radius(scene);
  std::vector<Light> directional;
  for (uint32_t i = 0; i < scene.directional_lights.size(); ++i) {
    if (auto light = DeltaDirectionalLight::make(scene, i, radius)) {
      directional.emplace_back(*light);
      ++directional_count_;
    }
  }
  // A few suns: each sampled at every vertex. Many: chosen like the rest.
  auto& into = directional.size() <= kAlwaysSampled ? always_ : lights_;
  into.insert(into.end(), directional.begin(), directional.end());
  if (auto env = EnvironmentLight::make(scene, radius)) {
    if (env->constant()) {
      unsampled_environment_ = std::move(*env);
    } else {
      environment_ = static_cast<int32_t>(lights_.size());
      lights_.emplace_back(std::move(*env));
    }
  }
  std::vector<double> powers;
  std::vector<std::optional<LightBounds>> bounds;
  for (const Light& light : lights_) {
    std::visit(
        [&](const auto& l) {
          powers.push_back(l.power());
          if constexpr (requires { l.bounds(); }) {
            bounds.emplace_back(l.bounds());
          } else {
            bounds.emplace_back();  // at infinity: chosen by power beside the tree
          }
        },
        light);
  }
  selection_ = LightSelection(powers, bounds, choice);
}

}  // namespace rayfarm
