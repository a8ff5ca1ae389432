#include "master/submission_queue.h"

#include "common/protocol/codec.h"
#include "common/protocol/convert.h"

namespace rayfarm::master {

SubmissionQueue::SubmissionQueue(const JobManager& jobs, Limits limits)
    : jobs_(jobs), limits_(std::move(limits)), thread_([this] { loop(); }) {}

SubmissionQueue::~SubmissionQueue() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

bool SubmissionQueue::add(const net::PeerId& peer, std::string label, std::string user,
                          wire::SubmitJob job, uint64_t bytes) {
  std::lock_guard lock(mutex_);
  const size_t from_peer = per_peer_.count(peer) ? per_peer_.at(peer) : 0;
  const size_t from_key = per_key_.count(user) ? per_key_.at(user) : 0;
  if (in_flight_ >= kMaxSubmissionsInFlight || from_peer >= kMaxSubmissionsPerPeer ||
      from_key >= kMaxSubmissionsPerKey ||
      (in_flight_ > 0 && bytes_ + bytes > 2 * limits_.max_bundle_bytes)) {
    return false;
  }
  ++in_flight_;
  ++per_peer_[peer];
  ++per_key_[user];
  bytes_ += bytes;
  const uint64_t jobs = protocol::frame_count(job.frames());
  jobs_in_flight_ += jobs;
  queue_.push_back(Task{peer, std::move(label), std::move(user), std::move(job), bytes, jobs});
  wake_.notify_one();
  return true;
}

std::vector<SubmissionQueue::Done> SubmissionQueue::take_done() {
  std::lock_guard lock(mutex_);
  std::vector<Done> out;
  out.swap(done_);
  for (const Done& d : out) {
    --in_flight_;
    jobs_in_flight_ -= d.jobs;
    bytes_ -= d.bytes;
    if (--per_peer_[d.peer] == 0) per_peer_.erase(d.peer);
    if (--per_key_[d.user] == 0) per_key_.erase(d.user);
  }
  return out;
}

size_t SubmissionQueue::in_flight() const {
  std::lock_guard lock(mutex_);
  return in_flight_;
}

uint64_t SubmissionQueue::jobs_in_flight() const {
  std::lock_guard lock(mutex_);
  return jobs_in_flight_;
}

void SubmissionQueue::drain() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [this] { return queue_.empty() && !busy_; });
}

void SubmissionQueue::loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, nothing left
    Task task = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
    Done done{task.peer,
              std::move(task.label),
              protocol::printable(task.job.scene_path(), 200),
              std::nullopt,
              "",
              task.user,
              task.bytes,
              false,
              task.jobs};
    try {
      // The scene parser checks the limits before it loads any mesh.
      done.job = jobs_.prepare(task.job, task.user, scene_check(task.job, limits_));
    } catch (const JobRejected& e) {
      done.error = e.what();
    } catch (const std::exception& e) {
      done.error = std::string("the master failed to check the job: ") + e.what();
      done.internal = true;
    }
    lock.lock();
    done_.push_back(std::move(done));
    busy_ = false;
    idle_.notify_all();
  }
}

}  // namespace rayfarm::master
