#include "common/util/read_file.h"

#include <fstream>
#include <system_error>

namespace rayfarm {
namespace fs = std::filesystem;

std::string read_whole_file(const fs::path& file, std::uintmax_t max_bytes) {
  using Kind = FileReadError::Kind;
  std::error_code error;
  const fs::file_status status = fs::status(file, error);
  if (error || !fs::exists(status)) throw FileReadError(Kind::kNotFound, 0, "file not found");
  if (!fs::is_regular_file(status)) throw FileReadError(Kind::kNotAFile, 0, "not a regular file");
  const std::uintmax_t size = fs::file_size(file, error);
  if (error) {
    throw FileReadError(Kind::kUnreadable, 0, "cannot read the file size: " + error.message());
  }
  if (size > max_bytes) {
    throw FileReadError(Kind::kTooLarge, size,
                        "the file has " + std::to_string(size) + " bytes, more than the limit of " +
                            std::to_string(max_bytes));
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    throw FileReadError(Kind::kUnreadable, size, "cannot open the file");
  }
  std::string text(static_cast<size_t>(size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    throw FileReadError(Kind::kUnreadable, size, "cannot read the file");
  }
  return text;
}

std::optional<std::string> try_read_whole_file(const fs::path& file, std::uintmax_t max_bytes) {
  try {
    return read_whole_file(file, max_bytes);
  } catch (const FileReadError&) {
    return std::nullopt;
  }
}

}  // namespace rayfarm
