#include "renderer/renderer.h"

#include "common/util/text.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <set>
#include <stdexcept>
#include <variant>

#include <fmt/format.h>

#include "common/image/fixed.h"
#include "common/scene/motion.h"
#include "common/util/log.h"
#include "renderer/camera.h"
#include "renderer/integrators/path_integrator.h"
#include "renderer/lights/light_set.h"
#include "renderer/pixel_filter.h"
#include "renderer/scene_data.h"

namespace rayfarm {

namespace {

// One integrator per BSDF the renderer can be built with, chosen once per job: the basic kinds'
// when the scene uses no other (every kind's code is the same in each, so the image is too), all
// kinds otherwise, or diffuse only on request (BsdfKinds).
using AnyIntegrator = std::variant<PathIntegratorFor<Bsdf>, PathIntegratorFor<DiffuseOnlyBsdf>,
                                   PathIntegratorFor<BasicBsdf>>;

AnyIntegrator make_integrator(const SceneData& data, const LightSet& lights,
                              const RenderSettings& settings, BsdfKinds kinds) {
  if (kinds == BsdfKinds::kDiffuseOnly) {
    for (const Material& m : data.scene().materials) {
      if (!DiffuseOnlyBsdf::supports(m)) {
        throw std::runtime_error("material '" + m.name + "' is " + material_kind_name(m.kind) +
                                 ", and this renderer (diffuse only, for benchmarks) renders "
                                 "diffuse materials only");
      }
    }
    return AnyIntegrator(std::in_place_index<1>, data, lights, settings);
  }
  const auto& materials = data.scene().materials;
  if (kinds == BsdfKinds::kAll &&
      std::all_of(materials.begin(), materials.end(), BasicBsdf::supports))
    return AnyIntegrator(std::in_place_index<2>, data, lights, settings);
  return AnyIntegrator(std::in_place_index<0>, data, lights, settings);
}

}  // namespace

struct Renderer::Impl {
  RenderSettings settings;
  SceneData data;
  LightSet lights;
  AnyIntegrator integrator;
  CameraModel camera;
  FilterSampler filter;
  MovingCamera moving_camera;  // empty unless the camera moves within the shutter
  bool timed = false;          // something moves: each sample draws its time
  mutable std::mutex stats_mutex;
  mutable RenderStats totals;     // guarded by stats_mutex
  mutable bool reported = false;  // guarded by stats_mutex

  Impl(const Scene& scene, const RenderSettings& s, BsdfKinds kinds, LightChoice choice)
      : settings(s),
        data(scene),
        lights(data, choice),
        integrator(make_integrator(data, lights, s, kinds)),
        camera(scene.camera, scene.film),
        filter(scene.filter, scene.film),
        moving_camera(scene.camera, scene.motion ? scene.motion->cameras : std::vector<Camera>{},
                      scene.film),
        timed(data.moves() || !moving_camera.empty()) {}

  // Renders samples [begin, end) of one pixel into its fixed-point sums.
  template <class Integrator>
  void render_pixel(const Integrator& path, uint32_t x, uint32_t y, const SampleRange& samples,
                    Fixed* sum, Fixed* sum_sq, uint64_t& nonfinite, PathStats& paths) const {
    const uint64_t pixel = uint64_t{y} * data.scene().film.width + x;
    for (uint32_t s = samples.begin; s < samples.end; ++s) {
      PathSampler sampler(settings.sampler, settings.seed, pixel, s);
      const std::array<float, 4> u = sampler.camera();
      float fx = static_cast<float>(x) + u[0], fy = static_cast<float>(y) + u[1];
      float weight = 1.f;  // the filter's weight (renderer/pixel_filter.h)
      if (!filter.pixel_box()) {
        const FilterSampler::Offset ox = filter.sample_x(x, u[0]), oy = filter.sample_y(y, u[1]);
        fx = ox.position;
        fy = oy.position;
        weight = ox.weight * oy.weight;
      }
      Ray ray;
      if (!timed) {
        ray = camera.generate(fx, fy, u[2], u[3]);
      } else {
        const float time = sampler.time();
        ray = moving_camera.empty() ? camera.generate(fx, fy, u[2], u[3])
                                    : moving_camera.generate(fx, fy, u[2], u[3], time);
        ray.time = time;
      }
      const Vec3 l = path.li(ray, sampler, paths);
      // A sample that is NaN, infinite or beyond the accumulator's range never reaches the film.
      if (!is_finite(l) || max_component(abs(l)) > kMaxSampleValue) {
        ++nonfinite;
        continue;
      }
      // --clamp: the sample scaled down so that its largest component is the clamp (biased).
      const float largest = max_component(l);
      const float scale =
          settings.clamp > 0.f && largest > settings.clamp ? settings.clamp / largest : 1.f;
      const float factor = scale * weight;  // scale itself without a filter
      if (weight != 1.f && max_component(abs(l)) * std::fabs(factor) > kMaxSampleValue) {
        ++nonfinite;
        continue;
      }
      for (int c = 0; c < 3; ++c) {
        const double v = l[c] * factor;
        sum[c] += to_fixed(v);
        sum_sq[c] += to_fixed(v * v);
      }
    }
  }

  const IntegratorPlan& plan() const {
    return std::visit([](const auto& path) -> const IntegratorPlan& { return path.plan(); },
                      integrator);
  }
};

namespace {

/// A renderer of an animated scene with an open shutter needs the scene's motion found for the
/// same shutter (add_motion()): without it the image would silently not be blurred.
const Scene& check_motion(const Scene& scene, const RenderSettings& settings) {
  if (!scene.animation || !settings.shutter_is_open()) return scene;
  const SceneMotion* m = scene.motion.get();
  if (m == nullptr ||
      m->steps() != std::clamp(settings.motion_steps, kMinMotionSteps, kMaxMotionSteps) ||
      m->times.front() != double(settings.shutter_open) ||
      m->times.back() != double(settings.shutter_close))
    throw std::runtime_error(
        "the shutter is open, but the scene's motion within it was not found for these settings "
        "(add_motion)");
  return scene;
}

}  // namespace

Renderer::Renderer(const Scene& scene, const RenderSettings& settings, BsdfKinds kinds,
                   LightChoice choice)
    : impl_(std::make_unique<Impl>(check_motion(scene, settings), settings, kinds, choice)) {}

Renderer::~Renderer() {
  try {
    if (!impl_->reported && impl_->totals.truncated_paths > 0) report_truncation();
  } catch (...) {  // logging must not throw out of a destructor
  }
}

double RenderStats::truncated_fraction() const {
  return samples > 0 ? double(truncated_paths) / double(samples) : 0.0;
}

double RenderStats::truncated_throughput_per_sample() const {
  return samples > 0 ? truncated_throughput / double(samples) : 0.0;
}

RenderStats& RenderStats::operator+=(const RenderStats& other) {
  samples += other.samples;
  rays += other.rays;
  truncated_paths += other.truncated_paths;
  truncated_throughput += other.truncated_throughput;
  return *this;
}

RenderStats Renderer::stats() const {
  std::lock_guard lock(impl_->stats_mutex);
  return impl_->totals;
}

std::string Renderer::report_truncation() const {
  std::lock_guard lock(impl_->stats_mutex);
  const RenderStats& t = impl_->totals;
  impl_->reported = true;
  const double cut = t.truncated_throughput_per_sample();
  std::string line = fmt::format(
      "max_depth {} stopped {} of {} paths ({:.3g}%) that still carried weight; throughput cut "
      "{:.3g} per sample",
      impl_->settings.max_depth, t.truncated_paths, t.samples, 100.0 * t.truncated_fraction(), cut);
  if (cut >= kTruncationWarningLevel) {
    line +=
        "; the light those paths would have gathered beyond the cap is missing from the "
        "image (a bias of the order of the throughput cut): raise max_depth";
    get_logger("render")->warn("{}", line);
  } else {
    get_logger("render")->debug("{}", line);
  }
  return line;
}

const RenderSettings& Renderer::settings() const { return impl_->settings; }
FilmSize Renderer::film() const { return impl_->data.scene().film; }

TileResult Renderer::render(const TileRect& rect, const SampleRange& samples,
                            RenderStats* stats) const {
  TileResult result;
  render(rect, samples, result, stats);
  return result;
}

void Renderer::render(const TileRect& rect, const SampleRange& samples, TileResult& result,
                      RenderStats* stats) const {
  result.reset(rect, samples);
  std::mutex totals_mutex;
  uint64_t nonfinite = 0;  // guarded by totals_mutex, as is `paths`
  PathStats paths;
  // One dispatch per unit; the integrator's type is fixed inside the loops.
  std::visit(
      [&](const auto& path) {
        tbb::parallel_for(tbb::blocked_range<uint32_t>(rect.y0, rect.y1),
                          [&](const tbb::blocked_range<uint32_t>& rows) {
                            uint64_t local_nonfinite = 0;
                            PathStats local;
                            for (uint32_t y = rows.begin(); y < rows.end(); ++y) {
                              for (uint32_t x = rect.x0; x < rect.x1; ++x) {
                                const size_t i =
                                    (size_t{y - rect.y0} * rect.width() + (x - rect.x0)) * 3;
                                impl_->render_pixel(path, x, y, samples, &result.sum[i],
                                                    &result.sum_sq[i], local_nonfinite, local);
                              }
                            }
                            std::lock_guard lock(totals_mutex);
                            nonfinite += local_nonfinite;
                            paths += local;
                          });
      },
      impl_->integrator);
  result.nonfinite = nonfinite;
  result.rays = paths.rays;
  RenderStats unit;
  unit.samples = uint64_t{rect.pixel_count()} * samples.count();
  unit.rays = paths.rays;
  unit.truncated_paths = paths.truncated;
  unit.truncated_throughput = paths.truncated_throughput;
  {
    std::lock_guard lock(impl_->stats_mutex);
    impl_->totals += unit;
  }
  if (stats != nullptr) *stats = unit;
}

namespace {

/// Which of the optional surface features the scene uses, by count of materials.
std::string surface_features(const SceneData& data) {
  size_t normal = 0, bump = 0, alpha = 0, emission = 0, tangent = 0, one_sided = 0;
  for (uint32_t i = 0; i < data.scene().materials.size(); ++i) {
    const Material& m = data.material(i);
    normal += m.normal_map.has_value();
    bump += m.bump_map.has_value();
    alpha += m.has_alpha();
    emission += m.emission.is_textured();
    tangent += (data.surface_needs(i) & kNeedsTangentFrame) != 0;
    one_sided += m.one_sided;
  }
  bool mesh_tangents = false;
  for (const TriangleMesh& mesh : data.scene().meshes) mesh_tangents |= !mesh.tangents.empty();
  for (const MeshGroup& g : data.scene().groups) {
    for (const TriangleMesh& mesh : g.meshes) mesh_tangents |= !mesh.tangents.empty();
  }
  std::string out;
  const auto add = [&out](size_t count, const char* what) {
    if (count > 0) out += (out.empty() ? "" : ", ") + std::to_string(count) + " " + what;
  };
  add(normal, "normal-mapped");
  add(bump, "bump-mapped");
  add(alpha, "with cut-outs");
  add(emission, "with textured emission");
  add(tangent, "anisotropic along the tangent");
  add(one_sided, "one-sided");
  if (out.empty()) return "plain";
  return out + " (materials)" +
         (normal + bump + tangent > 0
              ? std::string(mesh_tangents ? "; tangents from meshes" : "; tangents from UVs")
              : "");
}

}  // namespace

std::string Renderer::plan() const {
  const IntegratorPlan& p = impl_->plan();
  std::string out = std::string("integrator ") + integrator_name(p.integrator);
  const LightSet& lights = impl_->lights;
  const size_t area = lights.area_light_count(), point = lights.point_light_count();
  const size_t delta = point + lights.spot_light_count() + lights.directional_light_count();
  if (lights.empty() && lights.environment() == nullptr) {
    out += "; no lights, no light sampling";
  } else {
    out += "; " + std::to_string(area) + " emitters, " + std::to_string(point) + " point, " +
           std::to_string(lights.spot_light_count()) + " spot, " +
           std::to_string(lights.directional_light_count()) + " directional lights";
    if (!p.sample_lights) {
      out += ", not sampled";
    } else if (lights.selection().uses_tree()) {
      out += ", chosen through a light tree (" +
             std::to_string(lights.selection().tree().node_count()) + " nodes, depth " +
             std::to_string(lights.selection().tree().depth()) + ")";
    } else {
      out += ", power-sampled";
    }
    if (p.integrator == IntegratorType::kNaive && delta > 0) {
      out +=
          " (BSDF sampling never reaches point, spot or directional lights: they add nothing "
          "under naive)";
    }
    if (p.integrator == IntegratorType::kMis && !p.weight_emission && p.sample_lights) {
      out += " (no MIS weights: no area lights or environment)";
    }
    if (p.sample_lights && !lights.always_sampled().empty()) {
      out += "; " + std::to_string(lights.always_sampled().size()) +
             " directional sampled at every vertex";
    }
    if (const EnvironmentLight* env = lights.environment()) {
      if (lights.environment_unsampled()) {
        out +=
            "; constant environment, found by escaping rays (BSDF sampling draws it as well "
            "as light sampling could)";
      } else {
        out += "; environment " + std::to_string(env->width()) + "x" +
               std::to_string(env->height()) +
               (p.sample_lights ? ", sampled by luminance x sin(theta)" +
                                      std::string(p.weight_emission ? ", MIS-weighted" : "")
                                : ", found by escaping rays only");
      }
    }
  }
  std::set<std::string> kinds;
  for (const Material& m : impl_->data.scene().materials) kinds.insert(material_kind_name(m.kind));
  out += "; materials:";
  bool first = true;
  for (const auto& k : kinds) {
    out += (first ? " " : ", ") + k;
    first = false;
  }
  const TextureSet& textures = impl_->data.textures();
  if (textures.texture_count() == 0) {
    out += "; no textures";
  } else {
    out += "; " + std::to_string(textures.texture_count()) + " textures over " +
           std::to_string(textures.image_count()) + " images (" +
           human_bytes(textures.memory_bytes()) + ")";
  }
  out += "; surfaces: " + surface_features(impl_->data);
  const SceneData& data = impl_->data;
  if (data.instances() > 0 || data.flattened_instances() > 0) {
    out += "; " + std::to_string(data.instances()) + " instances of " +
           std::to_string(data.scene().groups.size()) + " groups";
    if (data.flattened_instances() > 0)
      out += " (" + std::to_string(data.flattened_instances()) +
             " more of emissive groups placed as world meshes)";
  }
  out +=
      "; max_depth " + depth_name(p.max_depth) + ", " + roulette_name(p.roulette) + " roulette" +
      (p.roulette != RouletteType::kUpdate ? " from vertex " + std::to_string(p.roulette_depth)
                                               : std::string()) +
      ", " + sampler_name(impl_->settings.sampler) + " sampler";
  if (p.specular_targets > 0)
    out += fmt::format("; aims a quarter of diffuse bounces at {} mirror or glass object{}",
                       p.specular_targets, p.specular_targets == 1 ? "" : "s");
  if (const SceneMotion* m = data.scene().motion.get()) {
    out += fmt::format("; shutter [{:g}, {:g}] frames, {} poses: ", m->times.front(),
                       m->times.back(), m->steps());
    if (!m->moves()) {
      out += "nothing moves";
    } else {
      out += fmt::format("{} meshes, {} spheres, {} placements{} move", m->meshes.size(),
                         m->spheres.size(), m->instances.size(),
                         m->cameras.empty() ? "" : " and the camera");
    }
    if (!m->still.empty()) out += fmt::format(" ({} drawn still)", m->still.size());
  }
  return out;
}

}  // namespace rayfarm
