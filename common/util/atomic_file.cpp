#include "common/util/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <fstream>
#include <mutex>
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

std::mutex g_fault_mutex;
std::function<int(const fs::path&)> g_fault;

void check_fault(const fs::path& path) {
  std::lock_guard lock(g_fault_mutex);
  if (!g_fault) return;
  if (const int error = g_fault(path)) {
    throw std::system_error(error, std::generic_category(), "cannot write " + path.string());
  }
}

}  // namespace

void set_write_fault_for_testing(std::function<int(const fs::path&)> fault) {
  std::lock_guard lock(g_fault_mutex);
  g_fault = std::move(fault);
}

int storage_error_code(const std::exception& e) {
  if (const auto* system = dynamic_cast<const std::system_error*>(&e)) return system->code().value();
  const std::string what = e.what();
  for (const int code : {ENOSPC, EDQUOT, EROFS, EIO, EACCES}) {
    if (what.find(std::generic_category().message(code)) != std::string::npos) return code;
  }
  return 0;
}

bool is_storage_error(const std::exception& e) {
  const int code = storage_error_code(e);
  return code == ENOSPC || code == EDQUOT || code == EROFS;
}

void write_bytes(const fs::path& path, std::string_view bytes) {
  check_fault(path);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0)
    throw std::system_error(errno, std::generic_category(), "cannot create " + path.string());
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : EIO;
      ::close(fd);
      throw std::system_error(error, std::generic_category(), "cannot write " + path.string());
    }
    done += static_cast<size_t>(n);
  }
  if (::close(fd) != 0) {
    throw std::system_error(errno, std::generic_category(), "cannot write " + path.string());
  }
}

void sync_folder(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) {
    const int error = errno;
    if (fd >= 0) ::close(fd);
    throw std::system_error(error, std::generic_category(), "cannot sync " + dir.string());
  }
  ::close(fd);
}

void write_atomically(const fs::path& path,
                      const std::function<void(const fs::path& temporary)>& write, Sync sync) {
  const fs::path temporary = temporary_path(path);
  try {
    check_fault(path);
    write(temporary);
    sync_file(temporary);
    fs::rename(temporary, path);
    if (sync == Sync::kFileAndFolder) sync_folder(path.parent_path());
  } catch (const std::exception& e) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw std::runtime_error("cannot write " + path.string() + ": " + e.what());
  }
}

void write_file_atomically(const fs::path& path, const std::string& bytes, Sync sync) {
  write_atomically(
      path, [&](const fs::path& temporary) { write_bytes(temporary, bytes); }, sync);
}

}  // namespace rayfarm
