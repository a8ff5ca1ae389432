#include "master/memory_return.h"

#include <malloc.h>

#include "common/util/log.h"

namespace rayfarm::master {

void tune_allocator() {
  // Setting either threshold turns off glibc's raising of both after a large free.
  ::mallopt(M_MMAP_THRESHOLD, static_cast<int>(MemoryReturn::kMapThresholdBytes));
  ::mallopt(M_TRIM_THRESHOLD, static_cast<int>(2 * MemoryReturn::kMapThresholdBytes));
}

uint64_t MemoryReturn::tick(Clock::time_point now) {
  if (now < next_) return 0;
  next_ = now + kInterval;
  // Free bytes held in every arena (chunks in bins and the tops of the heaps).
  const struct mallinfo2 info = ::mallinfo2();
  const uint64_t free_bytes = info.fordblks;
  if (free_bytes <= kTrimAboveBytes) return 0;
  ::malloc_trim(0);
  get_logger("master")->debug("gave back free memory: {:.1f} MB were held free",
                              static_cast<double>(free_bytes) / 1e6);
  return free_bytes;
}

}  // namespace rayfarm::master
