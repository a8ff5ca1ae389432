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

#include "common/scene/frames.h"

namespace rayfarm::cli {

enum class OutputFormat {
  kExr,  ///< "x.exr": the float EXR (variance and spp layers) and an sRGB preview "x.png" beside it
  kPng,  ///< "x.png": the sRGB preview alone (of a sequence: its contact sheet)
  kMp4,  ///< "x.mp4": a sequence's movie (`fetch` only)
};

/// The format `path` asks for (.exr or .png, any case; .mp4 too when `movie`), once its folder is
/// known to exist and to be writable. Throws std::invalid_argument naming the path and what to do
/// otherwise.
inline OutputFormat check_output_path(const std::filesystem::path& path, bool movie = false) {
  namespace fs = std::filesystem;
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  OutputFormat format;
  if (ext == ".exr") {
    format = OutputFormat::kExr;
  } else if (ext == ".png") {
    format = OutputFormat::kPng;
  } else if (movie && ext == ".mp4") {
    format = OutputFormat::kMp4;
  } else {
    throw std::invalid_argument(
        "output " + path.string() +
        ": the name must end in .exr (the image, with a PNG preview beside it) or .png (the "
        "preview alone)" +
        (movie ? std::string(", or .mp4 (a sequence's movie)") : std::string()));
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
  return rayfarm::has_frame_pattern(path.filename().string());
}

/// The image of frame `frame` of a sequence rendered to `path`: a run of '#' in the file name
/// becomes the frame number padded with zeros to its length ("shot.####.exr" -> "shot.0012.exr"),
/// as does a printf "%d" or "%0Nd"; a name with neither gets ".NNNN" before its extension
/// ("out.exr" -> "out.0012.exr").
inline std::filesystem::path frame_output_path(const std::filesystem::path& path, int64_t frame) {
  const std::string name = path.filename().string();
  if (!rayfarm::has_frame_pattern(name)) {
    const std::string ext = path.extension().string();
    return path.parent_path() /
           (name.substr(0, name.size() - ext.size()) + "." + substitute_frame("####", frame) + ext);
  }
  try {
    return path.parent_path() / substitute_frame(name, frame);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("output " + path.string() + ": " + e.what());
  }
}

}  // namespace rayfarm::cli
