#include "worker/unit_runner.h"

#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "common/util/log.h"
#include "renderer/renderer.h"

namespace rayfarm::worker {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("worker"); }

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

/// Everything a job's scene and renderer depend on: units with the same key share them.
std::string unit_key(const wire::WorkUnit& unit) {
  return unit.job_id() + '\0' + unit.bundle_hash() + '\0' + unit.scene_path() + '\0' +
         unit.settings().SerializeAsString() + '\0' + std::to_string(unit.film_width()) + 'x' +
         std::to_string(unit.film_height()) + '\0' +
         (unit.has_frame() ? std::to_string(unit.frame()) : std::string("still"));
}

}  // namespace

/// The scene and renderer of one job, identified by everything they depend on.
struct UnitRunner::Prepared {
  std::string key;
  std::string job_id;
  std::unique_ptr<Scene> scene;  // outlives the renderer built from it
  std::unique_ptr<Renderer> renderer;
};

UnitRunner::UnitRunner(uint32_t threads, uint32_t units_at_once, fs::path cache_dir)
    : cache_dir_(std::move(cache_dir)),
      arena_(threads == 0 ? tbb::task_arena::automatic : static_cast<int>(threads)),
      capacity_(units_at_once != 0 ? units_at_once : (arena_.max_concurrency() >= 2 ? 2 : 1)) {
  for (size_t i = 0; i < capacity_; ++i) render_threads_.emplace_back([this] { render_loop(); });
}

UnitRunner::~UnitRunner() {
  {
    std::lock_guard lock(mutex_);
    shutting_down_ = true;
  }
  work_cv_.notify_all();
  for (auto& t : render_threads_) t.join();
}

void UnitRunner::start(wire::WorkUnit unit) {
  ++in_hand_;
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(std::move(unit));
  }
  work_cv_.notify_one();
}

std::vector<UnitRunner::Finished> UnitRunner::take_finished(std::chrono::milliseconds wait) {
  std::vector<Finished> out;
  {
    std::unique_lock lock(mutex_);
    finished_cv_.wait_for(lock, wait, [&] { return !finished_.empty(); });
    out.swap(finished_);
  }
  in_hand_ -= out.size();
  return out;
}

std::vector<UnitRunner::Finished> UnitRunner::take_finished() {
  std::vector<Finished> out;
  {
    std::unique_lock lock(mutex_);
    finished_cv_.wait(lock, [&] { return !finished_.empty(); });
    out.swap(finished_);
  }
  in_hand_ -= out.size();
  return out;
}

void UnitRunner::log_job_stats() {
  std::lock_guard lock(mutex_);
  log_job_stats_locked();
}

void UnitRunner::log_job_stats_locked() {
  if (stats_.units == 0) return;
  log()->info("job {}: rendered {} units, {:.3g} samples in {:.2f} s", stats_.job_id, stats_.units,
              static_cast<double>(stats_.samples), stats_.seconds);
}

void UnitRunner::render_loop() {
  std::unique_lock lock(mutex_);
  while (true) {
    work_cv_.wait(lock, [&] { return shutting_down_ || !queue_.empty(); });
    if (shutting_down_) return;
    wire::WorkUnit unit = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    Finished finished = render(std::move(unit));
    lock.lock();
    finished_.push_back(std::move(finished));
    finished_cv_.notify_one();
  }
}

std::shared_ptr<const UnitRunner::Prepared> UnitRunner::prepare(const wire::WorkUnit& unit) {
  const std::string key = unit_key(unit);
  std::lock_guard prepare_lock(prepare_mutex_);
  {
    std::lock_guard lock(mutex_);
    if (prepared_ && prepared_->key == key) return prepared_;
  }
  const auto start = Clock::now();
  auto p = std::make_shared<Prepared>();
  p->key = key;
  p->job_id = unit.job_id();
  const std::filesystem::path bundle = cache_dir_ / unit.bundle_hash();
  const std::optional<int64_t> frame =
      unit.has_frame() ? std::optional<int64_t>(unit.frame()) : std::nullopt;
  p->scene = std::make_unique<Scene>(
      load_scene(bundle / unit.scene_path(), {}, SceneImages::kKeep, {}, bundle, frame));
  if (unit.film_width() != 0 && unit.film_height() != 0) {  // the job's film
    p->scene->film = {unit.film_width(), unit.film_height()};
  }
  const RenderSettings settings = protocol::settings_from_wire(unit.settings());
  const size_t warned = p->scene->warnings.size();
  add_motion(*p->scene, settings, {}, bundle);  // the poses within an open shutter
  for (size_t i = warned; i < p->scene->warnings.size(); ++i)
    log()->warn("job {}: {}", unit.job_id(), p->scene->warnings[i]);
  arena_.execute([&] { p->renderer = std::make_unique<Renderer>(*p->scene, settings); });
  drop_images(*p->scene);  // the renderer holds its own texels
  log()->info(
      "job {}: {}{} {}x{}, {} spp, {}, seed {}; renderer ready in {:.2f} s ({} threads, {} units "
      "at once): {}",
      unit.job_id(), unit.scene_path(), frame ? fmt::format(" frame {}", *frame) : "",
      p->scene->film.width, p->scene->film.height, settings.spp,
      integrator_name(settings.integrator), settings.seed, seconds_since(start), threads(),
      capacity_, p->renderer->plan());
  std::lock_guard lock(mutex_);
  if (stats_.job_id != p->job_id) {
    log_job_stats_locked();
    stats_ = JobStats{p->job_id};
  }
  prepared_ = p;
  return p;
}

UnitRunner::Finished UnitRunner::render(wire::WorkUnit unit) {
  Finished out;
  try {
    const std::shared_ptr<const Prepared> p = prepare(unit);
    const TileRect rect = protocol::rect_from_wire(unit.tile());
    if (unit.sample_end() <= unit.sample_begin()) {
      throw protocol::ProtocolError("empty sample range");
    }
    const SampleRange samples{unit.sample_begin(), unit.sample_end()};
    const auto start = Clock::now();
    TileResult result;
    arena_.execute([&] { result = p->renderer->render(rect, samples); });
    const double seconds = seconds_since(start);
    {
      std::lock_guard lock(mutex_);
      if (stats_.job_id == unit.job_id()) {
        ++stats_.units;
        stats_.samples += uint64_t{rect.pixel_count()} * samples.count();
        stats_.seconds += seconds;
      }
    }
    log()->debug("job {} unit {} (pass {}): tile [{},{})x[{},{}) samples [{},{}) in {:.3f} s",
                 unit.job_id(), unit.unit_id(), unit.pass(), rect.x0, rect.x1, rect.y0, rect.y1,
                 samples.begin, samples.end, seconds);
    out.result = protocol::result_to_wire(unit.job_id(), unit.unit_id(), result, seconds);
    out.ok = true;
  } catch (const std::exception& e) {
    out.error = e.what();
  }
  out.unit = std::move(unit);
  return out;
}

}  // namespace rayfarm::worker
