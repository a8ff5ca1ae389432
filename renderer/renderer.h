#pragma once
// The renderer that workers and `rayfarm render` run: one scene, one set of settings, and any
// number of units of work (tile x sample range). Thread-safe: render() may run concurrently.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "common/image/film.h"
#include "common/scene/scene.h"
#include "common/schedule/stop_rules.h"
#include "renderer/lights/light_selection.h"

namespace rayfarm {

/// What rendering did besides the image: not part of a TileResult, not sent on the wire.
struct RenderStats {
  uint64_t samples = 0;          ///< camera samples rendered
  uint64_t rays = 0;             ///< closest-hit and shadow rays traced
  uint64_t truncated_paths = 0;  ///< paths stopped by max_depth while still carrying weight
  /// Sum over those paths of their throughput (largest RGB component) when stopped.
  double truncated_throughput = 0.0;

  /// Fraction of samples whose path max_depth stopped while it still carried weight.
  double truncated_fraction() const;
  /// Throughput cut per sample: roughly the relative bias the cap puts on the image.
  double truncated_throughput_per_sample() const;
  RenderStats& operator+=(const RenderStats& other);
};

/// Throughput cut per sample above which the truncation is logged as a warning (0.1%).
inline constexpr double kTruncationWarningLevel = 1e-3;

/// The material kinds a Renderer's BSDF knows: all of them (through the kinds without
/// microfacets alone when the scene has no other: the same bits, faster), only diffuse (a
/// renderer for measuring what the other kinds cost a diffuse scene, bench/diffuse_only.sh), or
/// every kind whatever the scene (to check that the choice changes no bit).
enum class BsdfKinds : uint8_t { kAll, kDiffuseOnly, kEveryKind };

class Renderer {
 public:
  /// Builds the acceleration structure and light tables. Throws std::runtime_error on failure,
  /// and when the scene has a material whose kind `kinds` leaves out.
  /// `lights`: how shading points choose a light (light_selection.h; kAuto for renders, the
  /// others for tests and benchmarks that compare the two).
  Renderer(const Scene& scene, const RenderSettings& settings, BsdfKinds kinds = BsdfKinds::kAll,
           LightChoice lights = LightChoice::kAuto);
  /// Logs the truncation summary (report_truncation) if nobody has yet.
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Renders samples `samples` of every pixel in `rect`; parallel over rows in the calling
  /// thread's TBB arena. The result depends only on (scene, settings, rect, samples).
  /// `stats`, when given, receives this unit's statistics (they also add to stats()).
  TileResult render(const TileRect& rect, const SampleRange& samples,
                    RenderStats* stats = nullptr) const;
  /// render() into `result` (TileResult::reset() first), reusing its buffers: for callers that
  /// render unit after unit.
  void render(const TileRect& rect, const SampleRange& samples, TileResult& result,
              RenderStats* stats = nullptr) const;

  /// Statistics of every render() so far.
  RenderStats stats() const;

  /// Logs, once, how many paths max_depth cut while they still carried weight and how much:
  /// a warning (logger "render") when the throughput cut per sample reaches
  /// kTruncationWarningLevel, a debug line otherwise. Returns the line.
  std::string report_truncation() const;

  /// One line describing what this scene needs, e.g.
  /// "integrator mis; 3 emitters, power-sampled; materials: diffuse, mirror, dielectric".
  std::string plan() const;

  const RenderSettings& settings() const;
  FilmSize film() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Progress of a local render, reported after every merged unit and once more at the end.
struct RenderProgress {
  uint64_t units_done = 0;
  uint64_t units_total = 0;     ///< every tile for every pass: the most the render can need
  uint64_t units_released = 0;  ///< units needed so far (all of them without a target error)
  uint32_t rounds_done = 0;     ///< leading passes merged by every tile still rendering
  uint32_t passes_total = 0;
  uint32_t tiles_converged = 0, tiles_total = 0;
  double seconds = 0.0;
  StopReason reason = StopReason::kRunning;  ///< set in the last report
};

/// Options of a local render; the farm uses the same tiles, passes and stopping rules.
struct LocalRenderOptions {
  uint32_t threads = 0;    ///< 0 = all hardware threads
  uint32_t tile_size = kDefaultTileSize;
  uint32_t pass_spp = 0;   ///< 0 = default_pass_spp(tile_size, spp)
  StopRules stop;          ///< besides the spp: target error, time limit
  std::function<void(const RenderProgress&, const Film&)> on_progress;  ///< may be empty
};

/// Renders the image on this machine: every unit the stopping rules need (pass_planner.h), pass
/// by pass. With a target error (and no time limit) the image equals the farm's bit for bit.
Film render_local(const Renderer& renderer, const LocalRenderOptions& options);

}  // namespace rayfarm
