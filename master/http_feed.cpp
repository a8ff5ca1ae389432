#include "master/http_feed.h"

namespace rayfarm::master {

std::shared_ptr<const FarmSnapshot> HttpFeed::snapshot(std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  const auto now = Clock::now();
  last_look_ = now;
  const auto stale = [&] {
    return !snapshot_ || Clock::now() - snapshot_->taken > kSnapshotInterval * 3;
  };
  if (stale() && !closed_) published_.wait_for(lock, wait, [&] { return closed_ || !stale(); });
  return snapshot_;
}

std::optional<std::future<HttpAnswer>> HttpFeed::call(HttpCall call) {
  std::lock_guard lock(mutex_);
  if (closed_) {
    std::promise<HttpAnswer> stopping;
    stopping.set_value(HttpAnswer{503, "the master is stopping", nullptr});
    return stopping.get_future();
  }
  if (calls_.size() >= kMaxCalls) return std::nullopt;
  calls_.push_back(Pending{std::move(call), {}});
  return calls_.back().answer.get_future();
}

bool HttpFeed::snapshot_due(Clock::time_point now) const {
  std::lock_guard lock(mutex_);
  if (now - last_look_ > kWatchWindow) return false;
  return !snapshot_ || now - snapshot_->taken >= kSnapshotInterval;
}

void HttpFeed::publish(FarmSnapshot snapshot) {
  auto shared = std::make_shared<const FarmSnapshot>(std::move(snapshot));
  {
    std::lock_guard lock(mutex_);
    snapshot_ = std::move(shared);
  }
  published_.notify_all();
}

void HttpFeed::close() {
  std::vector<Pending> waiting;
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
    waiting.swap(calls_);
  }
  for (Pending& p : waiting) p.answer.set_value(HttpAnswer{503, "the master is stopping", nullptr});
  published_.notify_all();
}

std::vector<HttpFeed::Pending> HttpFeed::take_calls() {
  std::lock_guard lock(mutex_);
  std::vector<Pending> out;
  out.swap(calls_);
  return out;
}

}  // namespace rayfarm::master
