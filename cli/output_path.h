#pragma once
// Where `rayfarm render`, `fetch` and `submit --wait -o` write an image, checked before any work:
// the extension chooses the format, and the folder must exist and be writable, so that a typo
// never costs a whole render and a preview never overwrites the image it previews.
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
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

/// Whether `path`'s file name holds a frame number pattern (a '#' or a '%').
inline bool has_frame_pattern(const std::filesystem::path& path) {
  const std::string name = path.filename().string();
  return name.find('#') != std::string::npos || name.find('%') != std::string::npos;
}

/// The image of frame `frame` of a sequence rendered to `path`: a run of '#' in the file name
/// becomes the frame number padded with zeros to its length ("shot.####.exr" -> "shot.0012.exr"),
/// as does a printf "%d" or "%0Nd"; a name with neither gets ".NNNN" before its extension
/// ("out.exr" -> "out.0012.exr").
inline std::filesystem::path frame_output_path(const std::filesystem::path& path, int64_t frame) {
  const auto padded = [frame](size_t width) {
    char digits[32];
    std::snprintf(digits, sizeof digits, "%0*lld", int(std::min<size_t>(width, 12)),
                  static_cast<long long>(frame));
    return std::string(digits);
  };
  std::string name = path.filename().string();
  if (const size_t hash = name.find('#'); hash != std::string::npos) {
    size_t end = hash;
    while (end < name.size() && name[end] == '#') ++end;
    name.replace(hash, end - hash, padded(end - hash));
  } else if (const size_t pct = name.find('%'); pct != std::string::npos) {
    size_t at = pct + 1, width = 0;
    while (at < name.size() && std::isdigit(static_cast<unsigned char>(name[at])) != 0) {
      width = width * 10 + size_t(name[at] - '0');
      if (width > 12) width = 12;
      ++at;
    }
    if (at < name.size() && name[at] == 'd') {
      name.replace(pct, at + 1 - pct, padded(width));
    } else {
      throw std::invalid_argument("output " + path.string() +
                                  ": a '%' in the name must be a frame number, %d or %04d");
    }
  } else {
    const std::string ext = path.extension().string();
    name = name.substr(0, name.size() - ext.size()) + "." + padded(4) + ext;
  }
  return path.parent_path() / name;
}

}  // namespace rayfarm::cli
