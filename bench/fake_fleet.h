#pragma once
// Fake workers for farm_merge_bench: many worker connections (one ZeroMQ DEALER each, so many
// identities to the master) multiplexed over a few threads, in a ZeroMQ context of their own so
// that the master's I/O thread serves only the master. Each fake worker says Hello, asks for one
// unit, and answers each unit with a result of the right shape (packed sums, as a real worker's)
// followed by its next WorkRequest: at once (flat out), or `unit_seconds` after the lease (paced;
// a worker's first unit takes a random fraction of that, so that results arrive spread evenly).
// A fake worker that has sent nothing for a second sends a heartbeat, as a real one does.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/image/film.h"

namespace rayfarm::bench {

/// A result of the right shape for the unit, with sums that samples could have (the master
/// refuses impossible ones): mean m in [0.25, 0.31], second moment m^2 + 0.01.
TileResult fake_result(const TileRect& rect, const SampleRange& samples);

struct FleetOptions {
  int workers = 4;
  int threads = 2;          ///< threads the workers are spread over
  double unit_seconds = 0;  ///< 0: flat out
};

/// What the fleet sent so far (counted when sent, read from any thread).
struct FleetCounters {
  std::atomic<uint64_t> results{0};
  std::atomic<uint64_t> bytes{0};      ///< of the results, all frames
  std::atomic<uint64_t> units{0};      ///< units received
  std::atomic<uint64_t> connected{0};  ///< workers that got their first unit
  std::mutex mutex;
  std::string error;  ///< why a thread of the fleet stopped, under `mutex`; "" while it runs
};

class FakeFleet {
 public:
  /// Raises the process's open-file limit if the sockets need it, and starts the threads.
  FakeFleet(const std::string& endpoint, const FleetOptions& options);
  /// Stops the threads and closes the sockets.
  ~FakeFleet();
  FakeFleet(const FakeFleet&) = delete;
  FakeFleet& operator=(const FakeFleet&) = delete;

  FleetCounters& counters() { return counters_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  FleetCounters counters_;
  std::atomic<bool> stop_{false};
  std::vector<std::thread> threads_;
};

}  // namespace rayfarm::bench
