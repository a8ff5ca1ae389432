#include "worker/lights/light_set.h"

namespace rayfarm {

LightSet::LightSet(SceneData& data) {
  const Scene& scene = data.scene();
  // Area lights register their primitive, so that a BSDF ray hitting it finds its light index.
  const auto add_area = [&](const auto& light) {
    data.set_light_index(light.geom(), light.prim(), static_cast<int32_t>(lights_.size()));
    lights_.emplace_back(light);
  };
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    for (uint32_t t = 0; t < scene.meshes[m].triangle_count(); ++t) {
      if (auto light = TriangleLight::make(scene, m, t)) add_area(*light);
    }
  }
  for (uint32_t s = 0; s < scene.spheres.size(); ++s) {
    if (auto light = SphereLight::make(scene, s)) add_area(*light);
  }
  for (uint32_t i = 0; i < scene.point_lights.size(); ++i) {
    if (auto light = DeltaPointLight::make(scene, i)) {
      lights_.emplace_back(*light);
      ++point_count_;
    }
  }
  std::vector<double> powers;
  for (const Light& light : lights_) {
    powers.push_back(std::visit([](const auto& l) { return l.power(); }, light));
  }
  selection_ = PowerLightSelection(powers);
}

}  // namespace rayfarm
