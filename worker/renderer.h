#pragma once
// The renderer that workers and `rayfarm render` run: one scene, one set of settings, and any
// number of units of work (tile x sample range). Thread-safe: render() may run concurrently.
#include <functional>
#include <memory>
#include <string>

#include "common/image/film.h"
#include "common/scene/scene.h"

namespace rayfarm {

class Renderer {
 public:
  /// Builds the acceleration structure and light tables. Throws std::runtime_error on failure.
  Renderer(const Scene& scene, const RenderSettings& settings);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Renders samples `samples` of every pixel in `rect`; parallel over rows in the calling
  /// thread's TBB arena. The result depends only on (scene, settings, rect, samples).
  TileResult render(const TileRect& rect, const SampleRange& samples) const;

  /// One line describing what this scene needs, e.g.
  /// "integrator mis; 3 emitters, power-sampled; materials: diffuse, mirror, dielectric".
  std::string plan() const;

  const RenderSettings& settings() const;
  FilmSize film() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Progress of a local render, called after every merged unit.
struct RenderProgress {
  uint64_t units_done = 0, units_total = 0;
  uint32_t passes_done = 0, passes_total = 0;
  double seconds = 0.0;
};

/// Options of a local render; the farm uses the same tiles and passes.
struct LocalRenderOptions {
  uint32_t threads = 0;    ///< 0 = all hardware threads
  uint32_t tile_size = 64;
  uint32_t pass_spp = 0;   ///< 0 = default_pass_spp(tile_size, spp)
  std::function<void(const RenderProgress&, const Film&)> on_progress;  ///< may be empty
};

/// Renders the whole image on this machine: every tile for every pass, merged pass by pass.
Film render_local(const Renderer& renderer, const LocalRenderOptions& options);

}  // namespace rayfarm
