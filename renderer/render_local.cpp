#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>

#include "common/schedule/pass_planner.h"
#include "common/schedule/unit_grid.h"
#include "renderer/renderer.h"

namespace rayfarm {

Film render_local(const Renderer& renderer, const LocalRenderOptions& options) {
  using Clock = std::chrono::steady_clock;
  const RenderSettings& settings = renderer.settings();
  const FilmSize size = renderer.film();
  const uint32_t pass_spp =
      options.pass_spp > 0 ? options.pass_spp : default_pass_spp(options.tile_size, settings.spp);
  const UnitGrid grid(size, options.tile_size, settings.spp, pass_spp);
  PassPlanner planner(grid, options.stop);
  MergedUnits merged(grid);

  Film film(size.width, size.height);
  RenderProgress progress;
  progress.units_total = grid.size();
  progress.passes_total = grid.pass_count();
  progress.tiles_total = grid.tile_count();
  const auto start = Clock::now();
  const bool limited = options.stop.time_limit_s > 0;
  const auto deadline =
      start + std::chrono::duration_cast<Clock::duration>(
                  std::chrono::duration<double>(limited ? options.stop.time_limit_s : 0.0));
  std::atomic<bool> out_of_time{false};

  auto report = [&] {
    progress.units_released = planner.units_released();
    progress.rounds_done = planner.rounds_complete(merged);
    progress.tiles_converged = planner.tiles_converged();
    progress.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (options.on_progress) options.on_progress(progress, film);
  };

  tbb::task_arena arena(options.threads > 0 ? static_cast<int>(options.threads)
                                            : tbb::task_arena::automatic);
  std::mutex film_mutex;
  // Results merged, kept for the next units to render into (TileResult::reset): guarded by
  // film_mutex. At most one per unit in flight.
  std::vector<TileResult> spare;
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
      const uint32_t pass = grid.pass_of(ready.front());
      const auto end = std::find_if(ready.begin(), ready.end(),
                                    [&](uint64_t u) { return grid.pass_of(u) != pass; });
      const std::vector<uint64_t> wave(ready.begin(), end);
      ready.erase(ready.begin(), end);
      tbb::parallel_for(size_t{0}, wave.size(), [&](size_t i) {
        if (limited && (out_of_time || Clock::now() >= deadline)) {
          out_of_time = true;
          return;
        }
        const UnitGrid::Unit unit = grid.unit(wave[i]);
        TileResult result;
        {
          std::lock_guard lock(film_mutex);
          if (!spare.empty()) {
            result = std::move(spare.back());
            spare.pop_back();
          }
        }
        renderer.render(unit.rect, unit.samples, result);
        std::lock_guard lock(film_mutex);
        film.add(result);
        spare.push_back(std::move(result));
        merged.add(unit.id);
        planner.on_merged(unit.id, merged, film);
        progress.units_done = merged.count();
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
