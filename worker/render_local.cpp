#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <tbb/parallel_for.h>

#include <chrono>
#include <mutex>

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
  std::mutex film_mutex;
  arena.execute([&] {
    for (const SampleRange& pass : passes) {
      // Tiles of one pass in parallel (each also splits its rows); merging is exact, so the
      // order in which they finish does not matter.
      tbb::parallel_for(size_t{0}, tiles.size(), [&](size_t t) {
        TileResult result = renderer.render(tiles[t], pass);
        std::lock_guard lock(film_mutex);
        film.add(result);
        ++progress.units_done;
        progress.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (options.on_progress) options.on_progress(progress, film);
      });
      ++progress.passes_done;
    }
  });
  return film;
}

}  // namespace rayfarm
