#pragma once
// How many log lines a peer may cause, per kind of message: a burst per key and kind, refilled
// at a steady rate; past it, the caller logs the line at trace level only. The first line logged
// once a budget has room again says how many were held back since the previous one, so that a
// flood of messages of any kind from one key cannot flood the log while a few refusals or
// duplicates are all shown. kLogBudgets is the one table of the budgets (docs/reliability.md,
// "Log budgets").
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <utility>

#include <fmt/format.h>

namespace rayfarm::master {

/// The kinds of line a peer's messages make the master log.
enum class PeerLog : uint8_t {
  // The worker socket.
  kHello,           // a worker joined, or said hello as a client
  kDeparture,       // a worker left, was refused, became unreachable or was lost
  kNotRegistered,   // a heartbeat or other message from a connection that never said hello
  kBundleRequest,   // a bundle not sent: asked for again too soon, too many bytes, unknown
  kResultDropped,   // a result dropped: a duplicate, never leased to its sender, its job over
  kResultRejected,  // a leased result rejected: malformed, or its sums are impossible
  kUnitFailed,      // a failure report for a unit the connection does not hold
  // Both sockets.
  kMalformed,        // a message that cannot be decoded
  kProtocolVersion,  // a message of another protocol version
  kUnexpected,       // a message of a type the socket does not take
  // The client socket.
  kSubmissionRefused,  // a submission over a limit, or while the master is busy
  kForbidden,          // a change of another key's job, a priority above the key's limit
};

/// A kind's budget: `burst` lines at once, then one every `interval_s` seconds.
struct LogBudgetSpec {
  PeerLog kind;
  const char* name;  // as docs/reliability.md names it
  double burst;
  double interval_s;
};

/// The budgets, per key (per connection without keys) and kind.
inline constexpr std::array<LogBudgetSpec, 12> kLogBudgets{{
    {PeerLog::kHello, "worker hello", 64, 1},
    {PeerLog::kDeparture, "worker departure", 64, 1},
    {PeerLog::kNotRegistered, "message before hello", 4, 10},
    {PeerLog::kBundleRequest, "bundle request refused", 4, 10},
    {PeerLog::kResultDropped, "result dropped", 32, 1},
    {PeerLog::kResultRejected, "result rejected", 16, 1},
    {PeerLog::kUnitFailed, "failure of a unit not held", 1, 10},
    {PeerLog::kMalformed, "malformed message", 1, 10},
    {PeerLog::kProtocolVersion, "other protocol version", 1, 10},
    {PeerLog::kUnexpected, "unexpected message type", 1, 10},
    {PeerLog::kSubmissionRefused, "submission refused", 32, 1},
    {PeerLog::kForbidden, "request refused as not the key's", 8, 10},
}};

class LogBudget {
 public:
  using Clock = std::chrono::steady_clock;

  /// The budget of `kind` in kLogBudgets.
  static constexpr const LogBudgetSpec& spec(PeerLog kind) {
    for (const LogBudgetSpec& s : kLogBudgets) {
      if (s.kind == kind) return s;
    }
    return kLogBudgets[0];  // unreachable: every kind has its line (a test checks)
  }

  struct Verdict {
    bool log = false;         // whether to log the line at its own level
    uint64_t suppressed = 0;  // lines of this budget held back since its previous line
    double seconds = 0;       // since its previous line

    /// " (N similar lines suppressed in the last T s)" when lines were held back, else "".
    std::string suffix() const {
      if (!log || suppressed == 0) return {};
      return fmt::format(" ({} similar line{} suppressed in the last {:.1f} s)", suppressed,
                         suppressed == 1 ? "" : "s", seconds);
    }
  };

  /// Whether `who` may cause one more line of `kind` at `now` (and takes it).
  Verdict take(PeerLog kind, const std::string& who, Clock::time_point now = Clock::now()) {
    if (buckets_.size() > kMaxBuckets) buckets_.clear();
    const LogBudgetSpec& s = spec(kind);
    auto [it, fresh] = buckets_.try_emplace({kind, who});
    Bucket& b = it->second;
    if (fresh) {
      b.tokens = s.burst;
      b.refilled = b.logged = now;
    }
    const double refill = std::chrono::duration<double>(now - b.refilled).count() / s.interval_s;
    b.tokens = std::min(s.burst, b.tokens + std::max(refill, 0.0));
    b.refilled = now;
    if (b.tokens < 1) {
      ++b.suppressed;
      return {};
    }
    b.tokens -= 1;
    const Verdict verdict{true, b.suppressed,
                          std::chrono::duration<double>(now - b.logged).count()};
    b.suppressed = 0;
    b.logged = now;
    return verdict;
  }

 private:
  /// More keys than this at once (connections without keys, each its own): the budgets start
  /// over rather than grow.
  static constexpr size_t kMaxBuckets = 4096;
  struct Bucket {
    double tokens = 0;
    Clock::time_point refilled;
    Clock::time_point logged;  // its previous line
    uint64_t suppressed = 0;
  };
  std::map<std::pair<PeerLog, std::string>, Bucket> buckets_;
};

}  // namespace rayfarm::master
