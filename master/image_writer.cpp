#include "master/image_writer.h"
#include "master/metrics.h"

#include <chrono>

#include "common/image/film_output.h"
#include "common/image/png.h"
#include "common/util/log.h"

namespace rayfarm::master {

void ImageWriter::submit(const std::filesystem::path& exr, Image image, ErrorRecord record) {
  tasks_.submit(Task{exr, std::move(image), std::move(record)},
                [&](const Task& waiting) { return waiting.exr == exr; });
}

void ImageWriter::write(Task& task) {
  const auto start = std::chrono::steady_clock::now();
  auto took = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  try {
    write_exr(task.exr, task.image);
    write_png_preview(preview_path(task.exr), task.image);
    if (!task.record.rows.empty()) {
      const auto dir = task.exr.parent_path();
      write_error_csv(dir / "error.csv", task.record.rows);
      write_error_plot(dir / "error.png", task.record.rows, task.record.title);
    }
  } catch (const std::exception& e) {
    get_logger("jobs")->error("cannot write {}: {}", task.exr.string(), e.what());
    std::lock_guard lock(mutex_);
    failures_[task.exr] = e.what();
    seconds_[task.exr] = took();
    return;
  }
  const double seconds = took();
  metrics().image_write_seconds.observe(seconds);
  std::lock_guard lock(mutex_);
  failures_.erase(task.exr);
  seconds_[task.exr] = seconds;
}

double ImageWriter::seconds(const std::filesystem::path& exr) const {
  std::lock_guard lock(mutex_);
  auto it = seconds_.find(exr);
  return it == seconds_.end() ? 0.0 : it->second;
}

std::string ImageWriter::failure(const std::filesystem::path& exr) const {
  std::lock_guard lock(mutex_);
  auto it = failures_.find(exr);
  return it == failures_.end() ? std::string() : it->second;
}

}  // namespace rayfarm::master
