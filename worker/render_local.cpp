#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <chrono>

#include "worker/renderer.h"

namespace rayfarm {

Film render_local(const Renderer& renderer, const LocalRenderOptions& options) {
  const RenderSettings& settings = renderer.settings();
  const FilmSize size = renderer.film();
  const uint32_t pass_spp =
      options.pass_spp > 0 ? options.pass_spp : default_pass_spp(options.tile_size, settings.spp);
  const std::vector<TileRect> tiles = split_tiles(size, options.tile_size);
  const std::vector<SampleRange> passes = split_passes(settings.spp, pass_spp);

  Film film(size.width, size.height);
  RenderProgress progress;
  progress.units_total = uint64_t{tiles.size()} * passes.size();
  progress.passes_total = static_cast<uint32_t>(passes.size());
  const auto start = std::chrono::steady_clock::now();

  tbb::task_arena arena(options.threads > 0 ? static_cast<int>(options.threads)
                                            : tbb::task_arena::automatic);
  arena.execute([&] {
    for (const SampleRange& pass : passes) {
      for (const TileRect& tile : tiles) {
        film.add(renderer.render(tile, pass));
        ++progress.units_done;
        progress.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (options.on_progress) options.on_progress(progress, film);
      }
      ++progress.passes_done;
    }
  });
  return film;
}

}  // namespace rayfarm
