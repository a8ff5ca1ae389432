#pragma once
// A thread that writes files for the broker's reactor, so that the reactor only pays for queuing a
// copy of the data. Tasks run one at a time in the order queued; a task queued while an equal one
// (same file, same job) still waits replaces it in place, because only the newest state matters.
// Used for job images (image_writer.h) and checkpoints (checkpoint.h).
#include <algorithm>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>

namespace rayfarm::master {

template <class Task>
class BackgroundWriter {
 public:
  /// `run` writes one task on the writer's thread; it reports its own errors and must not throw.
  explicit BackgroundWriter(std::function<void(Task&)> run)
      : run_(std::move(run)), thread_([this] { loop(); }) {}
  /// Runs whatever is still queued, then stops the thread.
  ~BackgroundWriter() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  BackgroundWriter(const BackgroundWriter&) = delete;
  BackgroundWriter& operator=(const BackgroundWriter&) = delete;

  /// Queues `task`, in place of the first waiting task for which `same(waiting)` holds.
  template <class Same>
  void submit(Task task, Same same) {
    {
      std::lock_guard lock(mutex_);
      auto it = std::find_if(queue_.begin(), queue_.end(), same);
      if (it != queue_.end()) {
        *it = std::move(task);
      } else {
        queue_.push_back(std::move(task));
      }
    }
    wake_.notify_one();
  }

  /// Drops every waiting task for which `match(waiting)` holds (one being written completes).
  template <class Match>
  void discard(Match match) {
    std::lock_guard lock(mutex_);
    queue_.erase(std::remove_if(queue_.begin(), queue_.end(), match), queue_.end());
    if (queue_.empty() && !busy_) idle_.notify_all();
  }

  /// Returns when everything queued before the call has run.
  void flush() {
    std::unique_lock lock(mutex_);
    idle_.wait(lock, [&] { return queue_.empty() && !busy_; });
  }

 private:
  std::function<void(Task&)> run_;
  std::mutex mutex_;
  std::condition_variable wake_, idle_;
  std::deque<Task> queue_;
  bool busy_ = false;
  bool stopping_ = false;
  std::thread thread_;  // last: it starts with every other member in place

  void loop() {
    std::unique_lock lock(mutex_);
    while (true) {
      wake_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, nothing left
      Task task = std::move(queue_.front());
      queue_.pop_front();
      busy_ = true;
      lock.unlock();
      run_(task);
      lock.lock();
      busy_ = false;
      if (queue_.empty()) idle_.notify_all();
    }
  }
};

}  // namespace rayfarm::master
