#include "worker/bundle_cache.h"

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <system_error>

#include "common/bundle/bundle.h"
#include "common/protocol/convert.h"
#include "common/util/log.h"

namespace rayfarm::worker {
namespace fs = std::filesystem;

namespace {

std::shared_ptr<spdlog::logger> log() { return get_logger("worker"); }

/// The longest the master may make a worker wait before asking for a bundle again.
constexpr std::chrono::milliseconds kMaxRetryAfter{60000};

}  // namespace

BundleCache::BundleCache(fs::path dir) : dir_(std::move(dir)) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) {
    throw std::runtime_error("cannot create cache dir " + dir_.string() + ": " + ec.message());
  }
}

bool BundleCache::has(const std::string& hash) const {
  std::error_code ec;
  return fs::is_directory(dir_ / hash, ec);
}

void BundleCache::wait_for(wire::WorkUnit unit) { waiting_.push_back(std::move(unit)); }

std::optional<std::string> BundleCache::next_request() {
  if (!requested_.empty() || waiting_.empty() || Clock::now() < retry_) return std::nullopt;
  const wire::WorkUnit& unit = waiting_.front();
  log()->info("job {}: fetching bundle {} from the master", unit.job_id(),
              unit.bundle_hash().substr(0, 12));
  requested_ = unit.bundle_hash();
  return requested_;
}

BundleCache::Arrival BundleCache::on_reply(const wire::BundleReply& reply) {
  Arrival out;
  if (reply.hash() != requested_) {
    log()->debug("ignored an unrequested bundle {}", reply.hash().substr(0, 12));
    return out;
  }
  out.expected = true;
  requested_.clear();
  if (reply.retry_after_ms() > 0) {
    // Not refused: the master sends it later. The units keep waiting; next_request() asks again
    // once the time has passed.
    log()->info("the master will send bundle {} later: {}", reply.hash().substr(0, 12),
                reply.error());
    retry_ =
        Clock::now() + std::min(std::chrono::milliseconds{reply.retry_after_ms()}, kMaxRetryAfter);
    out.later = true;
    return out;
  }
  auto ready = std::stable_partition(
      waiting_.begin(), waiting_.end(),
      [&](const wire::WorkUnit& u) { return u.bundle_hash() != reply.hash(); });
  out.units.assign(std::make_move_iterator(ready), std::make_move_iterator(waiting_.end()));
  waiting_.erase(ready, waiting_.end());

  out.error = reply.error();
  if (out.error.empty()) {
    try {
      const Bundle bundle = protocol::bundle_from_wire(reply.bundle());
      const fs::path dir = unpack_bundle(bundle, dir_, reply.hash());
      log()->info("bundle {} cached in {} ({} files)", reply.hash().substr(0, 12), dir.string(),
                  bundle.files.size());
    } catch (const std::exception& e) {
      out.error = std::string("cannot unpack the bundle: ") + e.what();
    }
  }
  return out;
}

void BundleCache::forget_requests() {
  waiting_.clear();
  requested_.clear();
}

}  // namespace rayfarm::worker
