#include "common/util/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <fstream>
#include <system_error>

namespace rayfarm {
namespace fs = std::filesystem;
namespace {

fs::path temporary_path(const fs::path& path) {
  static std::atomic<uint64_t> counter{0};
  const std::string name = path.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                           std::to_string(counter.fetch_add(1));
  return path.parent_path() / name;
}

// Flushes a closed file's data to the disk, so the rename cannot expose an empty file after a
// crash. Throws std::system_error.
void sync_file(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::system_error(errno, std::generic_category(), "cannot reopen to sync");
  const int result = ::fsync(fd);
  const int sync_errno = errno;
  ::close(fd);
  if (result != 0) throw std::system_error(sync_errno, std::generic_category(), "fsync failed");
}

}  // namespace

void write_atomically(const fs::path& path,
                      const std::function<void(const fs::path& temporary)>& write) {
  const fs::path temporary = temporary_path(path);
  try {
    write(temporary);
    sync_file(temporary);
    fs::rename(temporary, path);
  } catch (const std::exception& e) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw std::runtime_error("cannot write " + path.string() + ": " + e.what());
  }
}

void write_file_atomically(const fs::path& path, const std::string& bytes) {
  write_atomically(path, [&](const fs::path& temporary) {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) throw std::runtime_error("short write to " + temporary.string());
  });
}

}  // namespace rayfarm
