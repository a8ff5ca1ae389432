#pragma once
// Giving memory back to the system after a burst. glibc keeps freed memory for reuse: buffers of
// a few megabytes (a large message, the sums of a large unit) come from its heap once one of that
// size was freed (its threshold for mapping them apart rises), and a flood of small messages
// leaves free pages in every thread's arena. Both stay in the master's resident memory after the
// burst is over. The master fixes the threshold at start (tune_allocator(): every buffer of
// kMapThresholdBytes or more is mapped apart and unmapped when freed) and, while it runs, has
// MemoryReturn hand back the free pages it still holds once they exceed kTrimAboveBytes.
#include <chrono>
#include <cstdint>

namespace rayfarm::master {

/// Sets the allocator's thresholds for the master process (call once, before any thread starts).
void tune_allocator();

class MemoryReturn {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr uint64_t kMapThresholdBytes = uint64_t{256} << 10;
  static constexpr uint64_t kTrimAboveBytes = uint64_t{32} << 20;
  static constexpr auto kInterval = std::chrono::seconds{5};

  /// At most once per kInterval: when the allocator holds more than kTrimAboveBytes free, gives
  /// the free pages back. Returns the bytes it found free (0 when it did not look or trim).
  uint64_t tick(Clock::time_point now = Clock::now());

 private:
  Clock::time_point next_ = Clock::now() + kInterval;
};

}  // namespace rayfarm::master
