#include "renderer/integrators/path_integrator.h"

#include <algorithm>
#include <optional>

namespace rayfarm {

template <class BsdfT>
PathIntegratorFor<BsdfT>::PathIntegratorFor(const SceneData& data, const LightSet& lights,
                                            const RenderSettings& settings)
    : data_(data), lights_(lights), background_(data.scene().background) {
  plan_.integrator = settings.integrator;
  plan_.max_depth = settings.max_depth;
  plan_.roulette = settings.roulette;
  plan_.roulette_depth = settings.roulette_depth;
  bool any_diffuse = false;
  for (const Material& m : data.scene().materials)
    any_diffuse |= m.textured || !BsdfT(m).is_specular();
  // Light sampling only where there are lights and surfaces that light sampling can serve.
  plan_.sample_lights =
      settings.integrator != IntegratorType::kNaive && !lights.empty() && any_diffuse;
  plan_.light_numbers = lights.reads_numbers();
  // MIS weights matter only when BSDF rays can also find the sampled emitters (area lights and
  // the environment).
  const bool hittable = lights.area_light_count() > 0 || lights.environment() != nullptr;
  plan_.weight_emission =
      plan_.sample_lights && settings.integrator == IntegratorType::kMis && hittable;
  plan_.emitters_reachable = hittable || !is_black(background_);
  plan_.escapes_count = !is_black(background_) || lights.environment_unsampled();
  plan_.light_tree = lights.selection().uses_tree();
  plan_.surface = data.uses_surface();
  plan_.plain = data.plain();
  // Specular objects worth aiming at: where BSDF rays can find emitters through them, from
  // surfaces that sample lights (the naive integrator stays plain BSDF sampling).
  // Not under update roulette, which would end aimed paths in proportion to the weight that
  // aiming takes from them.
  if (plan_.sample_lights && plan_.emitters_reachable &&
      settings.roulette != RouletteType::kUpdate) {
    std::vector<bool> specular;
    for (const Material& m : data.scene().materials)
      specular.push_back(!m.textured && !m.is_emissive() && BsdfT(m).is_specular());
    targets_ = SpecularTargets::of_scene(data.scene(), specular);
    plan_.specular_targets = static_cast<uint32_t>(targets_.targets().size());
  }
}

template <class BsdfT>
float PathIntegratorFor<BsdfT>::emission_weight(const SurfaceHit& hit, bool specular_bounce,
                                                float bsdf_pdf, const Vec3& prev_p,
                                                const Vec3& prev_n) const {
  // Emitters seen by the camera or through a specular chain, and emitters that light sampling
  // cannot choose (no area in float, or a negligible share of the power): only BSDF rays find
  // them.
  if (specular_bounce || !plan_.sample_lights || !lights_.selectable(hit.light)) return 1.f;
  // NEE: counted by light sampling, unless the light tree gave this light no chance from the
  // previous vertex (its importance there 0): then this ray alone finds it.
  if (!plan_.weight_emission)
    return lights_.selection_probability(hit.light, prev_p, prev_n) > 0.f ? 0.f : 1.f;
  return power_heuristic(bsdf_pdf, lights_.pdf(hit.light, prev_p, prev_n, hit.p, hit.n));
}

template <class BsdfT>
float PathIntegratorFor<BsdfT>::environment_weight(bool specular_bounce, float bsdf_pdf,
                                                   const Vec3& dir) const {
  // As emission_weight(), for the light that escaped rays find.
  if (specular_bounce || !plan_.sample_lights || !lights_.selectable(lights_.environment_index()))
    return 1.f;
  if (!plan_.weight_emission) return 0.f;
  return power_heuristic(bsdf_pdf, lights_.environment_pdf(dir));
}

template <class BsdfT>
Vec3 PathIntegratorFor<BsdfT>::sample_light(const SurfaceHit& hit, const Vec3& select_n, bool flat,
                                            const Vec3& wo, const Vec3& wo_local,
                                            const Frame& frame, const BsdfT& bsdf,
                                            const std::array<uint32_t, 3>& u,
                                            const TargetCones* cones, uint64_t& rays) const {
  // What one light sample brings: its shadow ray, and its MIS weight against the BSDF.
  const auto shade = [&](const LightSample& ls) __attribute__((always_inline))->Vec3 {
    const Vec3 wi_local = frame.to_local(ls.wi);
    if (!same_sides(hit, flat, wo, ls.wi, wo_local, wi_local)) return Vec3(0.f);
    if (!(wi_local.z > 0.f) && (data_.surface_needs(hit.material) & kShadingSided))
      return Vec3(0.f);
    const Vec3 f = bsdf.eval(wo_local, wi_local);
    if (is_black(f)) return Vec3(0.f);
    // Shadow ray from the offset origin to the (offset) light point, or without end to a light
    // at infinity.
    const Vec3 origin =
        offset_ray_origin(hit.p, hit.p_error, leaving_side(hit, flat, ls.wi, wi_local.z));
    ++rays;
    Ray shadow = ls.infinite ? Ray{origin, ls.wi} : Ray{origin, ls.target - origin, 0.f, 1.f};
    shadow.time = hit.time;
    if (data_.bvh().occluded(shadow)) return Vec3(0.f);
    float w = 1.f;
    if (!ls.delta && plan_.weight_emission) {
      // Against the density with which the vertex draws its next direction: the BSDF's, or its
      // mixture with the specular targets' cones.
      float bsdf_pdf = bsdf.pdf(wo_local, wi_local);
      if (cones)
        bsdf_pdf = (1.f - SpecularTargets::kShare) * bsdf_pdf +
                   SpecularTargets::kShare * cones->pdf(ls.wi);
      w = power_heuristic(ls.pdf, bsdf_pdf);
    }
    return f * ls.radiance * (w / ls.pdf);
  };
  Vec3 sum(0.f);
  // One light chosen among those that take turns, from the vertex's numbers.
  LightSample ls;
  if (lights_.sample(hit.p, select_n, SelectionNumber{u[0]}, sobol::to_unit_float(u[1]),
                     sobol::to_unit_float(u[2]), ls)) {
    sum += shade(ls);
  }
  // Each light sampled at every vertex (a sun): no numbers, no choice.
  for (const auto& light : lights_.always_sampled()) {
    LightSample always;
    const bool sampled = visit_chain(
        light, [&](const auto& l) __attribute__((always_inline)) {
          return l.sample(hit.p, 1.f, 0.f, 0.f, always);
        });
    if (sampled) sum += shade(always);
  }
  return sum;
}

template <class BsdfT>
bool PathIntegratorFor<BsdfT>::aim_sample(const BsdfT& bsdf, const TargetCones& cones,
                                          const Vec3& wo_local, const Frame& frame,
                                          const std::array<float, 3>& u, BsdfSample& bs,
                                          Vec3& wi) const {
  // One-sample MIS over the mixture: u[0] chooses the strategy and, rescaled, the lobe or cone.
  constexpr float kShare = SpecularTargets::kShare;
  constexpr float kBelowOne = 0x1.fffffep-1f;
  Vec3 f;
  if (u[0] < kShare) {
    wi = SpecularTargets::sample(cones, std::min(u[0] / kShare, kBelowOne), u[1], u[2]);
    bs.wi = frame.to_local(wi);
    bs.specular = false;
    bs.eta = 1.f;
    f = bsdf.eval(wo_local, bs.wi);
    bs.pdf = bsdf.pdf(wo_local, bs.wi);
  } else {
    if (!bsdf.sample(wo_local, std::min((u[0] - kShare) / (1.f - kShare), kBelowOne), u[1], u[2],
                     bs))
      return false;
    wi = frame.to_world(bs.wi);
    if (bs.specular) {  // a Dirac lobe, which the cones never draw
      bs.weight = bs.weight * (1.f / (1.f - kShare));
      return true;
    }
    f = bsdf.eval(wo_local, bs.wi);
  }
  const float pdf = (1.f - kShare) * bs.pdf + kShare * cones.pdf(wi);
  if (!(pdf > 0.f) || is_black(f)) return false;
  bs.pdf = pdf;
  bs.weight = f / pdf;
  return true;
}

template <class BsdfT>
Vec3 PathIntegratorFor<BsdfT>::li(Ray ray, PathSampler& sampler, PathStats& stats) const {
  // Scenes without surface features run a loop with no trace of them, and flat untextured
  // scenes one without the tests for shading normals and texture coordinates.
  if (plan_.surface) return trace<PathMode::kSurface>(ray, sampler, stats);
  if (plan_.plain) return trace<PathMode::kPlain>(ray, sampler, stats);
  return trace<PathMode::kGeneral>(ray, sampler, stats);
}

template <class BsdfT>
template <PathMode kMode>
Vec3 PathIntegratorFor<BsdfT>::trace(Ray ray, PathSampler& sampler, PathStats& stats) const {
  uint64_t& rays = stats.rays;
  // The cap stops a path that could still gather light: count it and the weight it carried.
  const auto truncate = [&stats](const Vec3& throughput) {
    const float w = max_component(throughput);
    if (w > 0.f) {
      ++stats.truncated;
      stats.truncated_throughput += w;
    }
  };
  Vec3 radiance(0.f), beta(1.f);
  float eta_scale = 1.f;  // product of eta^2 over the refractions so far (throughput roulette)
  const bool throughput_roulette = plan_.roulette != RouletteType::kUpdate;
  const bool root_roulette = plan_.roulette == RouletteType::kRoot;
  const float update_cap = plan_.max_depth > kUncappedUpdateDepth ? kMaxSurvival : 1.f;
  bool specular_bounce = true;  // the camera ray: emitters it sees count fully
  float bsdf_pdf = 0.f;
  Vec3 prev_p, prev_n;  // the previous vertex and its light selection normal (select_n)
  for (uint32_t depth = 0;; ++depth) {
    // Find the next vertex; escaped rays see the background.
    ++rays;
    RayHit rh;
    if (!data_.bvh().intersect(ray, rh)) {
      radiance += beta * background_;
      if (const EnvironmentLight* env = lights_.environment()) {
        const Vec3 le = env->eval(ray.dir);
        if (!is_black(le))
          radiance += beta * le * environment_weight(specular_bounce, bsdf_pdf, ray.dir);
      }
      break;
    }
    constexpr bool kPlain = kMode == PathMode::kPlain;
    SurfaceHit hit = kPlain ? data_.resolve_plain(ray, rh) : data_.resolve(ray, rh);
    const Material& material = data_.material(hit.material);
    const Vec3 wo = -ray.dir;  // camera and BSDF directions are unit vectors

    // Emission reached by BSDF sampling, weighted against light sampling.
    if (material.is_emissive()) {
      const Vec3 le =
          kPlain ? emitted_radiance(material, hit.n, wo)
                 : emitted_radiance(material, hit.n, wo, TextureLookup(&data_.textures(), hit.uv));
      if (!is_black(le))
        radiance += beta * le * emission_weight(hit, specular_bounce, bsdf_pdf, prev_p, prev_n);
    }
    if (depth == plan_.max_depth) {
      truncate(beta);
      break;
    }

    // Light sampling (NEE / MIS) at non-specular vertices, in the shading frame.
    Frame frame(kPlain ? hit.n : hit.ns);  // the same bits in a plain scene
    if constexpr (kMode == PathMode::kSurface) {
      // A one-sided surface seen from behind scatters nothing.
      if ((data_.surface_needs(hit.material) & kOneSided) && dot(wo, hit.n) < 0.f) break;
      frame = shade_surface(data_, rh, hit);
    }
    const bool flat = kPlain || is_flat(hit);  // after a normal map may have bent ns
    const Vec3 wo_local = frame.to_local(wo);
    bool shading_sided = false;
    if constexpr (kMode == PathMode::kSurface) {
      shading_sided = (data_.surface_needs(hit.material) & kShadingSided) != 0;
      if (shading_sided && !(wo_local.z > 0.f)) break;  // seen from below its shading horizon
    }
    const BsdfT bsdf =
        kPlain || !(material.textured || material.vertex_colours) ? BsdfT(material)
        : material.vertex_colours
            ? BsdfT(material, TextureLookup(&data_.textures(), hit.uv, data_.vertex_colour(rh)))
            : BsdfT(material, TextureLookup(&data_.textures(), hit.uv));
    // The side from which light selection takes light: wo's (geometric) side where the BSDF
    // only reflects (same_sides() rejects the other side), every side where it may transmit.
    const Vec3 select_n = plan_.light_tree && bsdf.reflects_only()
                              ? (dot(wo, hit.n) >= 0.f ? hit.n : -hit.n)
                              : Vec3(0.f);
    // The vertex's numbers are drawn before the light is sampled (light first, in the order the
    // independent sampler reads its stream): the BSDF's are ready when its sampling needs them.
    const bool sample_light_here = plan_.sample_lights && !bsdf.is_specular();
    const std::array<uint32_t, 3> light_u =
        sample_light_here ? sampler.light_bits(depth, plan_.light_numbers)
                          : std::array<uint32_t, 3>{};
    const std::array<float, 3> u = sampler.scatter(depth);
    // The specular targets' cones seen from here, if this vertex aims at them.
    TargetCones cones;
    bool aim = false;
    if (plan_.specular_targets > 0 && sample_light_here && bsdf.reflects_only()) {
      targets_.cones(hit.p, dot(wo, hit.n) >= 0.f ? hit.n : -hit.n, cones);
      aim = cones.count > 0;
    }
    if (sample_light_here) {
      radiance += beta * sample_light(hit, select_n, flat, wo, wo_local, frame, bsdf, light_u,
                                      aim ? &cones : nullptr, rays);
    }

    // BSDF sampling for the next direction, or a direction into a specular target's cone.
    BsdfSample bs;
    Vec3 wi;
    if (!aim) {
      if (!bsdf.sample(wo_local, u[0], u[1], u[2], bs)) break;
      wi = frame.to_world(bs.wi);
    } else if (!aim_sample(bsdf, cones, wo_local, frame, u, bs, wi)) {
      break;
    }
    if (!same_sides(hit, flat, wo, wi, wo_local, bs.wi)) break;
    if (shading_sided && !(bs.wi.z > 0.f)) break;

    if (throughput_roulette) {
      // Russian roulette on the path's throughput, the refractions' 1 / eta^2 undone (radiance
      // squeezed into glass is no reason to end the path), from roulette_depth on.
      beta *= bs.weight;
      eta_scale *= bs.eta * bs.eta;
      if (depth >= plan_.roulette_depth) {
        const float weight = max_component(beta) * eta_scale;
        if (!(weight > 0.f)) break;  // also NaN: 0 x an eta^2 that overflowed
        const float survive =
            root_roulette ? throughput_survival(weight) : std::min(kMaxSurvival, weight);
        if (!(sampler.roulette() < survive)) break;
        beta /= survive;
      } else if (!(max_component(beta) > 0.f)) {
        break;
      }
    } else {
      // Russian roulette with survival probability min(1, max component of the update).
      const float weight = max_component(bs.weight);
      if (!(weight > 0.f)) break;
      const float survive = std::min(update_cap, weight);
      if (!(sampler.roulette() < survive)) break;
      beta *= bs.weight / survive;
    }
    specular_bounce = bs.specular;
    bsdf_pdf = bs.pdf;
    prev_p = hit.p;
    prev_n = select_n;

    // The ray after the last scattering vertex matters only if it can find counted emission.
    // (Not with a light tree: NEE counts a BSDF ray's emitter that the tree could not choose.)
    const bool last_ray_useless =
        !plan_.emitters_reachable ||
        (!specular_bounce && plan_.sample_lights && !plan_.weight_emission && !plan_.light_tree &&
         !plan_.escapes_count);  // NEE: diffuse-bounce emitter and environment hits not counted
    if (depth + 1 == plan_.max_depth && last_ray_useless) {
      truncate(beta);
      break;
    }
    ray = Ray{offset_ray_origin(hit.p, hit.p_error, leaving_side(hit, flat, wi, bs.wi.z)), wi};
    ray.time = hit.time;
  }
  return radiance;
}

template class PathIntegratorFor<Bsdf>;
template class PathIntegratorFor<DiffuseOnlyBsdf>;
template class PathIntegratorFor<BasicBsdf>;

}  // namespace rayfarm
