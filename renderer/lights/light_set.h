#pragma once
// Every light of a scene, one type per kind (emissive triangles and spheres, point lights, spot
// lights with and without a projected image, directional lights, the environment), and how light
// sampling serves them at a shading point:
// - directional lights (a sun), up to kAlwaysSampled of them, are each sampled at every vertex:
//   one shadow ray each, no choice, so that a sun never loses its samples to the other lights;
// - a constant environment (a uniform sky) is not light-sampled at all: BSDF sampling draws it
//   as well as anything can, and rays that escape count it in full;
// - every other light is one light chosen per vertex (light_selection.h: by power, or through a
//   light tree), its sample weighted by MIS against BSDF sampling.
#include <cstdint>
#include <optional>
#include <type_traits>
#include <variant>
#include <vector>

#include "common/math/vec3.h"
#include "renderer/lights/directional_light.h"
#include "renderer/lights/environment_light.h"
#include "renderer/lights/image_spot_light.h"
#include "renderer/lights/light_sample.h"
#include "renderer/lights/light_selection.h"
#include "renderer/lights/point_light.h"
#include "renderer/lights/sphere_light.h"
#include "renderer/lights/spot_light.h"
#include "renderer/lights/textured_area_lights.h"
#include "renderer/lights/triangle_light.h"
#include "renderer/scene_data.h"
#include "renderer/variant_chain.h"

namespace rayfarm {

class LightSet {
 public:
  /// Every light kind. Adding one: its header, one line here, and its collection in the
  /// constructor (light_set.cpp).
  using Light = std::variant<TriangleLight, SphereLight, DeltaPointLight, DeltaSpotLight,
                             DeltaDirectionalLight, EnvironmentLight, TexturedTriangleLight,
                             TexturedSphereLight, ImageSpotLight>;

  /// Collects the lights of `data` and registers each emitter with data.set_light_index();
  /// `choice`: how a shading point chooses among them.
  explicit LightSet(SceneData& data, LightChoice choice = LightChoice::kAuto);

  /// Directional lights beyond this many are chosen with the others instead.
  static constexpr size_t kAlwaysSampled = 8;

  /// No light that light sampling serves (chosen, or always sampled).
  bool empty() const { return lights_.empty() && always_.empty(); }
  /// The lights that a vertex chooses one of; sample() draws from them.
  size_t size() const { return lights_.size(); }
  /// The lights sampled at every vertex, each with probability 1 (directional lights).
  const std::vector<Light>& always_sampled() const { return always_; }
  /// Emissive triangles and spheres.
  size_t area_light_count() const { return area_count_; }
  size_t point_light_count() const { return point_count_; }
  size_t spot_light_count() const { return spot_count_; }
  size_t directional_light_count() const { return directional_count_; }
  /// The environment, or null when the scene has none (or it emits nothing).
  const EnvironmentLight* environment() const {
    if (unsampled_environment_) return &*unsampled_environment_;
    return environment_ < 0 ? nullptr : &std::get<EnvironmentLight>(lights_[environment_]);
  }
  /// Whether the environment is there but left to BSDF sampling (a constant one): escaped rays
  /// count it with weight 1.
  bool environment_unsampled() const { return unsampled_environment_.has_value(); }
  /// Density with which sample() draws the escaping unit direction `dir` from the environment,
  /// selection included; 0 without one.
  float environment_pdf(const Vec3& dir) const {
    const EnvironmentLight* env = environment();
    if (env == nullptr) return 0.f;
    return selection_.infinite_probability(environment_) * env->pdf_direction(dir);
  }
  /// Index of the environment among the chosen lights, or -1 (none, or not light-sampled).
  int32_t environment_index() const { return environment_; }

  /// Chooses a light for the shading point `ref` with geometric normal `ref_n` (or the zero
  /// vector), and a point on it. False when the sample carries nothing.
  // Inlined into its one caller: as a call (it grew with the kinds' code) it cost more than the
  // sampling itself at -O3.
  [[gnu::always_inline]] bool sample(const Vec3& ref, const Vec3& ref_n, SelectionNumber select,
                                     float u1, float u2, LightSample& out) const {
    if (lights_.empty()) return false;
    int32_t index = -1;
    float p_select = 0.f;
    if (!selection_.choose(ref, ref_n, select, index, p_select)) return false;
    return visit_chain(
        lights_[index], [&](const auto& light) __attribute__((always_inline)) {
          return light.sample(ref, p_select, u1, u2, out);
        });
  }
  /// Whether sample() reads its numbers (the light's choice and the point on it). It does not
  /// when the scene has one light, chosen without a tree, of a kind whose sample() ignores them
  /// (the kind says so with `kReadsNumbers = false`: point, spot and directional lights): the
  /// sample is then the same whatever the numbers.
  bool reads_numbers() const {
    if (lights_.empty()) return false;  // only lights sampled always, which read none
    if (lights_.size() != 1 || selection_.uses_tree()) return true;
    return visit_chain(lights_.front(), [](const auto& light) {
      using L = std::decay_t<decltype(light)>;
      if constexpr (requires { L::kReadsNumbers; }) {
        return L::kReadsNumbers;
      } else {
        return true;
      }
    });
  }
  /// Whether sample() can choose light `light` somewhere (false for -1: an emitter it cannot
  /// sample, and for a light whose share of the power rounds to nothing).
  bool selectable(int32_t light) const { return selection_.selectable(light); }
  /// Probability that sample() at (ref, ref_n) chooses light `light` (0 for -1).
  float selection_probability(int32_t light, const Vec3& ref, const Vec3& ref_n) const {
    return selection_.probability(ref, ref_n, light);
  }
  /// How lights are chosen (light_selection.h).
  const LightSelection& selection() const { return selection_; }
  /// Density sample() at (ref, ref_n) would have had for reaching the emitter `light` at
  /// (p, n).
  float pdf(int32_t light, const Vec3& ref, const Vec3& ref_n, const Vec3& p, const Vec3& n) const {
    if (light < 0) return 0.f;
    const float p_select = selection_.probability(ref, ref_n, light);
    return visit_chain(lights_[light],
                       [&](const auto& l) { return l.pdf(p_select, ref, p, n); });
  }

 private:
  std::vector<Light> lights_;  // chosen one per vertex
  std::vector<Light> always_;  // sampled at every vertex
  std::optional<EnvironmentLight> unsampled_environment_;
  LightSelection selection_;
  size_t area_count_ = 0, point_count_ = 0, spot_count_ = 0, directional_count_ = 0;
  int32_t environment_ = -1;
};

}  // namespace rayfarm
