#pragma once
// Files that readers never see half-written: written beside the target, synced, then renamed.
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rayfarm {

/// What an atomic write syncs: the file (it is never seen half-written), or the file and then
/// its folder (the rename itself survives a crash too: checkpoints).
enum class Sync { kFile, kFileAndFolder };

/// Creates `path` atomically: `write` fills a fresh temporary file beside it, which is synced and
/// renamed over `path` (and the folder synced, with Sync::kFileAndFolder). On any failure the
/// temporary is removed and std::runtime_error says "cannot write PATH: cause".
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& temporary)>& write,
                      Sync sync = Sync::kFile);

/// Writes `bytes` to `path` atomically (see write_atomically).
void write_file_atomically(const std::filesystem::path& path, const std::string& bytes,
                           Sync sync = Sync::kFile);

/// Flushes the folder `dir` to the disk, so that the files created, renamed or removed in it
/// survive a crash. Throws std::system_error "cannot sync DIR: cause".
void sync_folder(const std::filesystem::path& dir);

/// Creates or truncates `path` and writes `bytes` to it, all of them or a std::system_error with
/// the cause the system gave (e.g. "No space left on device"). Not atomic by itself.
void write_bytes(const std::filesystem::path& path, std::string_view bytes);

/// For tests of storage faults (a full or read-only disk): while set, every write_bytes and
/// write_atomically first calls `fault` with the path; a non-zero errno it returns fails that write
/// with that cause. An empty function removes the hook. Not for production use.
void set_write_fault_for_testing(std::function<int(const std::filesystem::path&)> fault);

/// The system error behind `e`: its code when it is a std::system_error, else the first of the
/// storage errors (ENOSPC, EDQUOT, EROFS, EIO, EACCES) whose text its message holds (writers
/// wrap the system's message in their own); 0 when none.
int storage_error_code(const std::exception& e);

/// Whether `e` says the storage is full or read-only (ENOSPC, EDQUOT, EROFS), as opposed to bad
/// data.
bool is_storage_error(const std::exception& e);

}  // namespace rayfarm
