#include "master/image_writer.h"

#include <algorithm>

#include "common/image/film_output.h"
#include "common/image/png.h"
#include "common/util/log.h"

namespace rayfarm::master {

ImageWriter::ImageWriter() : thread_([this] { loop(); }) {}

ImageWriter::~ImageWriter() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void ImageWriter::submit(const std::filesystem::path& exr, Image image, ErrorRecord record) {
  {
    std::lock_guard lock(mutex_);
    auto same =
        std::find_if(queue_.begin(), queue_.end(), [&](const Task& t) { return t.exr == exr; });
    if (same != queue_.end()) {
      same->image = std::move(image);
      same->record = std::move(record);
    } else {
      queue_.push_back(Task{exr, std::move(image), std::move(record)});
    }
  }
  wake_.notify_one();
}

void ImageWriter::flush() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [&] { return queue_.empty() && !busy_; });
}

void ImageWriter::loop() {
  std::unique_lock lock(mutex_);
  while (true) {
    wake_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, nothing left
    Task task = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
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
    }
    lock.lock();
    busy_ = false;
    if (queue_.empty()) idle_.notify_all();
  }
}

}  // namespace rayfarm::master
