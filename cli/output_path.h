#pragma once
// Where `rayfarm render`, `fetch` and `submit --wait -o` write an image, checked before any work:
// the extension chooses the format, and the folder must exist and be writable, so that a typo
// never costs a whole render and a preview never overwrites the image it previews.
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

namespace rayfarm::cli {

enum class OutputFormat {
  kExr,  ///< "x.exr": the float EXR (variance and spp layers) and an sRGB preview "x.png" beside it
  kPng,  ///< "x.png": the sRGB preview alone
};

/// The format `path` asks for (.exr or .png, any case), once its folder is known to exist and to
/// be writable. Throws std::invalid_argument naming the path and what to do otherwise.
inline OutputFormat check_output_path(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  OutputFormat format;
  if (ext == ".exr") {
    format = OutputFormat::kExr;
  } else if (ext == ".png") {
    format = OutputFormat::kPng;
  } else {
    throw std::invalid_argument(
        "output " + path.string() +
        ": the name must end in .exr (the image, with a PNG preview beside it) or .png (the "
        "preview alone)");
  }
  const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    throw std::invalid_argument("output " + path.string() + ": the folder " + folder.string() +
                                " does not exist");
  }
  if (::access(folder.c_str(), W_OK | X_OK) != 0) {
    throw std::invalid_argument("output " + path.string() + ": the folder " + folder.string() +
                                " is not writable");
  }
  if (fs::is_directory(path, ec)) {
    throw std::invalid_argument("output " + path.string() + " is a folder");
  }
  return format;
}

}  // namespace rayfarm::cli
