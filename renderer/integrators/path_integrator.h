#pragma once
// The path tracer: naive (BSDF sampling only), NEE (one light per vertex, light_selection.h) and
// MIS (light and BSDF sampling, power heuristic), each with Russian roulette (on the path's
// throughput or on each vertex's update) and the max_depth cap of RenderSettings, if any.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf.h"
#include "renderer/integrators/specular_targets.h"
#include "renderer/lights/light_set.h"
#include "renderer/samplers/path_sampler.h"
#include "renderer/scene_data.h"
#include "renderer/surface_shading.h"

namespace rayfarm {

/// What a scene needs, decided once per job (see plan()).
struct IntegratorPlan {
  IntegratorType integrator = IntegratorType::kMis;
  bool sample_lights = false;     ///< NEE / MIS light sampling at non-specular vertices
  /// Light sampling reads its numbers (LightSet::reads_numbers()); without, the Sobol' sampler
  /// leaves them out.
  bool light_numbers = true;
  bool weight_emission = false;   ///< MIS weights on emitters hit by BSDF rays
  bool emitters_reachable = false;  ///< area lights or a background that BSDF rays can find
  /// Rays that escape count what they find in full under NEE too: a background colour, or an
  /// environment that light sampling leaves to them (a constant one, light_set.h).
  bool escapes_count = false;
  uint32_t max_depth = 0;           ///< kUnlimitedDepth: no cap
  RouletteType roulette = RouletteType::kRoot;
  uint32_t roulette_depth = 0;
  /// Lights are chosen through a light tree (light_selection.h): selection reads the vertex.
  bool light_tree = false;
  /// Some material has a normal or bump map, an anisotropic BSDF or one side only
  /// (surface_shading.h); without one the shading frame is the normal's alone.
  bool surface = false;
  /// Every hit is flat and nothing reads a texture (SceneData::plain()).
  bool plain = false;
  /// Specular objects that non-specular vertices which only reflect aim at (specular_targets.h):
  /// their BSDF sampling is mixed with sampling these objects' cones; 0 = none.
  uint32_t specular_targets = 0;
};

/// The path loop's variants, from what the scene uses (IntegratorPlan): each leaves out the
/// tests that the ones after it need.
enum class PathMode {
  kPlain,    ///< flat hits, no textures, no surface features
  kGeneral,  ///< vertex normals or textures, no surface features
  kSurface,  ///< normal or bump maps, tangent frames, one-sided materials
};

/// What paths did besides their radiance: rays traced, and paths that the max_depth cap stopped
/// while they still carried weight (their continuation is missing from the image: a bias).
struct PathStats {
  uint64_t rays = 0;       ///< closest-hit and shadow rays traced
  uint64_t truncated = 0;  ///< paths stopped by max_depth with non-zero throughput
  /// Sum over those paths of their throughput (largest RGB component) when stopped; per sample,
  /// about the fraction of the light beyond the cap that the image lacks.
  double truncated_throughput = 0.0;

  PathStats& operator+=(const PathStats& other) {
    rays += other.rays;
    truncated += other.truncated;
    truncated_throughput += other.truncated_throughput;
    return *this;
  }
};

/// The path tracer over the BSDF `BsdfT` (bsdf.h): `Bsdf` knows every material kind, `BasicBsdf`
/// the kinds without microfacets (the renderer's choice for scenes that use no other), and the
/// renderer instantiates it over `DiffuseOnlyBsdf` only for the benchmark of what the other
/// kinds cost (bench/diffuse_only.sh). Instantiated in path_integrator.cpp for those three.
template <class BsdfT>
class PathIntegratorFor {
 public:
  /// Every material of `data` must be one that BsdfT supports.
  PathIntegratorFor(const SceneData& data, const LightSet& lights, const RenderSettings& settings);

  /// Radiance arriving along `ray` (one sample); adds what the path did to `stats`.
  Vec3 li(Ray ray, PathSampler& sampler, PathStats& stats) const;

  const IntegratorPlan& plan() const { return plan_; }

 private:
  template <PathMode kMode>
  Vec3 trace(Ray ray, PathSampler& sampler, PathStats& stats) const;
  // Inlined into trace(): a call passes the hit, the frame and the BSDF through memory.
  [[gnu::always_inline]] inline Vec3 sample_light(const SurfaceHit& hit, const Vec3& select_n,
                                                  bool flat, const Vec3& wo, const Vec3& wo_local,
                                                  const Frame& frame, const BsdfT& bsdf,
                                                  const std::array<uint32_t, 3>& u,
                                                  const TargetCones* cones, uint64_t& rays) const;
  // The next direction from the mixture of BSDF sampling and the specular targets' cones, with
  // the mixture's weight and density; false when it carries nothing.
  [[gnu::always_inline]] inline bool aim_sample(const BsdfT& bsdf, const TargetCones& cones,
                                                const Vec3& wo_local, const Frame& frame,
                                                const std::array<float, 3>& u, BsdfSample& bs,
                                                Vec3& wi) const;
  float emission_weight(const SurfaceHit& hit, bool specular_bounce, float bsdf_pdf,
                        const Vec3& prev_p, const Vec3& prev_n) const;
  float environment_weight(bool specular_bounce, float bsdf_pdf, const Vec3& dir) const;

  const SceneData& data_;
  const LightSet& lights_;
  IntegratorPlan plan_;
  Vec3 background_;
  SpecularTargets targets_;
};

using PathIntegrator = PathIntegratorFor<Bsdf>;
extern template class PathIntegratorFor<Bsdf>;
extern template class PathIntegratorFor<DiffuseOnlyBsdf>;
extern template class PathIntegratorFor<BasicBsdf>;

/// Whether a hit is flat: its shading normal is the geometric one (bit for bit, as SceneData
/// makes it). Computed once per vertex: the comparison is three float compares that every
/// vertex of a flat scene would otherwise repeat at each check below.
inline bool is_flat(const SurfaceHit& hit) { return hit.ns == hit.n; }

/// Whether wi stays on the side of the surface, relative to wo, that the shading frame says it
/// does: a reflection in the shading frame must be one of the geometric surface too, and a
/// transmission a transmission, so that interpolated normals never carry light through a surface
/// or reflect it from behind. Always true at flat hits (`flat`: is_flat(hit)).
inline bool same_sides(const SurfaceHit& hit, bool flat, const Vec3& wo, const Vec3& wi,
                       const Vec3& wo_local, const Vec3& wi_local) {
  if (flat) return true;
  return (dot(wo, hit.n) * dot(wi, hit.n) > 0.f) == (wo_local.z * wi_local.z > 0.f);
}

/// The geometric normal on the side that wi leaves through, for offsetting its ray. At flat hits
/// the shading frame's z decides (it is the geometric one); at smooth hits the geometric normal
/// does, since wo may lie on different sides of the two.
inline Vec3 leaving_side(const SurfaceHit& hit, bool flat, const Vec3& wi, float wi_local_z) {
  const bool front = flat ? wi_local_z > 0.f : dot(wi, hit.n) > 0.f;
  return front ? hit.n : -hit.n;
}

/// Most probability with which roulette lets a path go on where it must end some day: throughput
/// roulette always, update roulette with a depth cap above 1024 or none. A path of perfect mirrors
/// (or a furnace of albedo 1) would otherwise never end; with it, a path survives 4096 such
/// vertices with probability 1/e. Below it sit all albedos up to 0.9998, whose estimates keep a
/// finite variance (that needs albedo^2 < the survival).
inline constexpr float kMaxSurvival = 1.f - 0x1p-12f;
/// Probability with which throughput roulette lets a path go on whose throughput (its largest
/// component, the refractions' 1 / eta^2 undone) is `weight`: the fourth root, up to
/// kMaxSurvival. Survival by the throughput itself ends dim paths early, the paths that carry
/// most of the light in the dark parts of an image (lit from far along the path, or through
/// glass and mirrors); the root spares them at first, and once the weights that survivors carry
/// settle (after a few vertices the throughput is about albedo^3) survival is the albedo per
/// vertex, as with the throughput itself, so path lengths keep the same geometric tail and the
/// same finite variance below kMaxSurvival (docs/benchmarks.md, "Russian roulette that spares
/// dim paths").
inline float throughput_survival(float weight) {
  return std::min(kMaxSurvival, std::sqrt(std::sqrt(weight)));
}
/// Deepest cap under which update roulette keeps survival min(1, update), the rule of jobs
/// stored when 1024 was the most a cap could be; above it (or with no cap) kMaxSurvival bounds it.
inline constexpr uint32_t kUncappedUpdateDepth = 1024;

/// Power heuristic (beta = 2) weight of a strategy with density a against one with density b.
inline float power_heuristic(float a, float b) {
  // Squares in double: a sharp lobe's density above ~1.8e19 squares to infinity in float, and
  // the weight became inf / inf = NaN.
  const double a2 = double(a) * a, b2 = double(b) * b;
  const double w = a2 / (a2 + b2);
  return w >= 0.0 ? static_cast<float>(w) : 0.f;  // also 0 for 0 / 0
}

}  // namespace rayfarm
