#pragma once
// An MP4 movie of 8-bit frames, encoded by ffmpeg in a process of its own: the frames are
// written to its standard input as raw RGB, so nothing but the movie touches the disk.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace rayfarm::master {

struct MovieSpec {
  /// The ffmpeg program: a path, or a name looked up in PATH.
  std::string ffmpeg = "ffmpeg";
  uint32_t width = 0;
  uint32_t height = 0;
  double fps = 24.0;
  size_t frames = 0;
  /// Frame i's pixels: width * height * 3 bytes of sRGB, row-major, top row first. May throw
  /// (the movie is then not written, and what() says why).
  std::function<std::vector<uint8_t>(size_t i)> frame;
};

/// Writes the movie to `path` atomically (H.264 in MP4, or MPEG-4 part 2 when this ffmpeg has no
/// H.264 encoder; odd sides padded to even). Returns "" on success, else why not: ffmpeg missing
/// ("ffmpeg not found"), its exit status and last error line, a frame that could not be read, a
/// `time_limit` passed (ffmpeg is killed), or `stop` set (likewise). Blocks SIGPIPE on the
/// calling thread.
std::string write_movie(const std::filesystem::path& path, const MovieSpec& movie,
                        std::chrono::seconds time_limit, const std::atomic<bool>& stop);

}  // namespace rayfarm::master
