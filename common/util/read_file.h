#pragma once
// Reading a whole file with a size cap: every reader of untrusted or user-given files goes
// through here, so that none of them can be made to allocate without bound.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

namespace rayfarm {

/// Why read_whole_file() failed; what() is the cause alone ("file not found"), for the caller to
/// put after its own name for the file.
class FileReadError : public std::runtime_error {
 public:
  enum class Kind { kNotFound, kNotAFile, kTooLarge, kUnreadable };
  FileReadError(Kind kind, std::uintmax_t size, const std::string& what)
      : std::runtime_error(what), kind_(kind), size_(size) {}
  Kind kind() const { return kind_; }
  /// The file's size in bytes, when known (always for kTooLarge).
  std::uintmax_t size() const { return size_; }

 private:
  Kind kind_;
  std::uintmax_t size_;
};

/// No cap: for files rayfarm wrote itself.
inline constexpr std::uintmax_t kNoSizeCap = UINTMAX_MAX;

/// The whole of `file`, at most `max_bytes` of it. Throws FileReadError: "file not found", "not a
/// regular file", "the file has N bytes, more than the limit of M", "cannot open the file",
/// "cannot read the file".
std::string read_whole_file(const std::filesystem::path& file, std::uintmax_t max_bytes);

/// read_whole_file(), or nullopt when the file cannot be read or is over `max_bytes`.
std::optional<std::string> try_read_whole_file(const std::filesystem::path& file,
                                               std::uintmax_t max_bytes = kNoSizeCap);

}  // namespace rayfarm
