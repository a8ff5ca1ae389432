#pragma once
// Files that readers never see half-written: written beside the target, synced, then renamed.
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>

namespace rayfarm {

/// Creates `path` atomically: `write` fills a fresh temporary file beside it, which is synced and
/// renamed over `path`. On any failure the temporary is removed and std::runtime_error says
/// "cannot write PATH: cause".
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& temporary)>& write);

/// Writes `bytes` to `path` atomically (see write_atomically).
void write_file_atomically(const std::filesystem::path& path, const std::string& bytes);

}  // namespace rayfarm
