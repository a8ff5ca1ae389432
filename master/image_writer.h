#pragma once
// Writes job images (EXR + PNG preview) on a thread of its own, so that the broker's reactor keeps
// serving heartbeats and results while a large image is compressed. Only the newest image of each
// file matters: one queued for a file that already has an unwritten one replaces it.
#include <filesystem>
#include <map>
#include <mutex>
#include <string>

#include "common/image/exr.h"
#include "common/report/error_log.h"
#include "master/background_writer.h"

namespace rayfarm::master {

class ImageWriter {
 public:
  /// The error record written with an image: error.csv and error.png in the image's folder.
  struct ErrorRecord {
    std::vector<ErrorRow> rows;
    std::string title;
  };

  /// Queues `image` for `exr` and its preview (common/image/film_output.h's preview_path), and
  /// the error record when it has rows.
  void submit(const std::filesystem::path& exr, Image image, ErrorRecord record = {});
  /// Returns when everything queued before the call is written (or failed, which is logged).
  void flush() { tasks_.flush(); }
  /// Why the latest write of `exr` (or its preview or error record) failed; "" when it succeeded
  /// or none was tried.
  std::string failure(const std::filesystem::path& exr) const;
  /// Seconds the latest write of `exr` (with its preview and error record) took; 0 before one.
  double seconds(const std::filesystem::path& exr) const;

 private:
  struct Task {
    std::filesystem::path exr;
    Image image;
    ErrorRecord record;
  };
  void write(Task& task);
  mutable std::mutex mutex_;                               // guards failures_ and seconds_
  std::map<std::filesystem::path, std::string> failures_;  // image -> why its latest write failed
  std::map<std::filesystem::path, double> seconds_;        // image -> what its latest write took
  BackgroundWriter<Task> tasks_{[this](Task& task) { write(task); }};  // last: uses the above
};

}  // namespace rayfarm::master
