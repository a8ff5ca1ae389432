#include "common/scene/scene_files.h"

#include "common/util/read_file.h"

namespace rayfarm {
namespace fs = std::filesystem;

std::string read_text_file(const fs::path& file, std::uintmax_t max_bytes,
                           const std::string& display) {
  try {
    return read_whole_file(file, max_bytes);
  } catch (const FileReadError& e) {
    throw SceneError(display + ": " + e.what());
  }
}

std::optional<fs::path> resolve_scene_path(const fs::path& base_dir, const std::string& reference,
                                           std::string* why) {
  if (reference.empty()) {
    *why = "the path is empty";
    return std::nullopt;
  }
  if (reference.find('\0') != std::string::npos) {
    *why = "the path contains a NUL character";
    return std::nullopt;
  }
  const fs::path path(reference);
  if (path.has_root_path()) {
    *why = "absolute paths are not allowed; give a path relative to the scene's folder";
    return std::nullopt;
  }
  const fs::path joined = (base_dir / path).lexically_normal();
  if (joined.empty() || *joined.begin() == "..") {
    *why = "the path leaves the scene's folder";
    return std::nullopt;
  }
  if (!joined.has_filename() || joined == ".") {
    *why = "the path names a folder, not a file";
    return std::nullopt;
  }
  return joined;
}

}  // namespace rayfarm
