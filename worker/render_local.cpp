#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>

#include "worker/renderer.h"

namespace rayfarm {

Film render_local(const Renderer& renderer, const LocalRenderOptions& options) {
  using Clock = std::chrono::steady_clock;
  const RenderSettings& settings = renderer.settings();
  const FilmSize size = renderer.film();
  const uint32_t pass_spp =
      options.pass_spp > 0 ? options.pass_spp : default_pass_spp(options.tile_size, settings.spp);
  const std::vector<TileRect> tiles = split_tiles(size, options.tile_size);
  const std::vector<SampleRange> passes = split_passes(settings.spp, pass_spp);
  const uint64_t tile_count = tiles.size();
  PassPlanner planner(tiles, static_cast<uint32_t>(passes.size()), pass_spp, options.stop);

  Film film(size.width, size.height);
  RenderProgress progress;
  progress.units_total = tile_count * passes.size();
  progress.passes_total = static_cast<uint32_t>(passes.size());
  progress.tiles_total = static_cast<uint32_t>(tile_count);
  const auto start = Clock::now();
  const bool limited = options.stop.time_limit_s > 0;
  const auto deadline =
      start + std::chrono::duration_cast<Clock::duration>(
                  std::chrono::duration<double>(limited ? options.stop.time_limit_s : 0.0));
  std::atomic<bool> out_of_time{false};

  auto report = [&] {
    progress.units_released = planner.units_released();
    progress.rounds_done = planner.rounds_complete();
    progress.tiles_converged = planner.tiles_converged();
    progress.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (options.on_progress) options.on_progress(progress, film);
  };

  tbb::task_arena arena(options.threads > 0 ? static_cast<int>(options.threads)
                                            : tbb::task_arena::automatic);
  std::mutex film_mutex;
  // Units go out pass by pass; the units of one pass run in parallel (each tile also splits its
  // rows). Merging is exact, so the order in which they finish does not matter.
  std::vector<uint64_t> ready;
  if (planner.gated()) {
    ready = planner.take_released();
  } else {
    ready.resize(progress.units_total);
    for (uint64_t u = 0; u < ready.size(); ++u) ready[u] = u;
  }
  arena.execute([&] {
    while (!ready.empty() && !out_of_time) {
      const uint64_t pass = ready.front() / tile_count;
      const auto end = std::find_if(ready.begin(), ready.end(),
                                    [&](uint64_t u) { return u / tile_count != pass; });
      const std::vector<uint64_t> wave(ready.begin(), end);
      ready.erase(ready.begin(), end);
      tbb::parallel_for(size_t{0}, wave.size(), [&](size_t i) {
        if (limited && (out_of_time || Clock::now() >= deadline)) {
          out_of_time = true;
          return;
        }
        const uint64_t unit = wave[i];
        TileResult result = renderer.render(tiles[unit % tile_count], passes[unit / tile_count]);
        std::lock_guard lock(film_mutex);
        film.add(result);
        planner.on_merged(unit, film);
        ++progress.units_done;
        report();
      });
      if (planner.gated()) {
        const std::vector<uint64_t> next = planner.take_released();
        ready.insert(ready.end(), next.begin(), next.end());
        std::sort(ready.begin(), ready.end());
      }
    }
  });
  progress.reason = planner.finished() ? planner.reason() : StopReason::kTimeLimit;
  report();
  return film;
}

}  // namespace rayfarm
