#pragma once
// A sequence's previews, made on a thread of their own so that the reactor never waits for them:
// a contact sheet of its finished frames (contact.png in the sequence's folder), rewritten as
// frames finish, and once every frame is done an MP4 movie of them (preview.mp4) made by ffmpeg,
// when the master has it. docs/farm.md, "Frame sequences".
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "common/image/contact_sheet.h"
#include "master/background_writer.h"

namespace rayfarm::master {

class SequencePreviews {
 public:
  static constexpr const char* kSheetName = "contact.png";
  static constexpr const char* kMovieName = "preview.mp4";

  struct Frame {
    int64_t frame = 0;
    std::filesystem::path exr;  ///< its final image
    bool done = false;
  };
  struct Request {
    std::string sequence;       ///< its id
    std::filesystem::path dir;  ///< its folder: the previews go there
    std::vector<Frame> frames;  ///< in frame order
    double fps = 24.0;          ///< of the movie
    bool sheet = true;          ///< (re)write the contact sheet
    bool movie = false;         ///< make the movie (every frame is done)
  };

  /// `ffmpeg`: the program, a path or a name looked up in PATH; "" makes no movies.
  explicit SequencePreviews(std::string ffmpeg = "ffmpeg");
  /// Stops a movie being made (it is made again at the next start), then the thread.
  ~SequencePreviews();

  /// Queues the sequence's previews, in place of a waiting request for the same sequence.
  void submit(Request request);
  /// Drops the sequence's waiting request, stops a movie of it being made and waits until
  /// nothing of it is being made (its folder is about to go); other sequences' work goes on.
  void forget(const std::string& sequence);
  /// Returns when everything queued before the call is made (or failed, which is logged).
  void flush() { tasks_.flush(); }
  /// Whether movies are made at all.
  bool makes_movies() const { return !ffmpeg_.empty(); }
  /// Why the sequence's latest movie was not made; "" when it was, or none was tried.
  std::string movie_failure(const std::string& sequence) const;

 private:
  void make(Request& request);
  void make_sheet(const Request& request);
  void make_movie(const Request& request);

  std::string ffmpeg_;
  std::atomic<bool> stopping_{false};
  std::atomic<bool> abort_current_{false};  // stops the movie being made (stopping, forget)
  mutable std::mutex mutex_;                // guards movie_failures_, current_, forgotten_
  std::condition_variable made_;            // current_ changed
  std::map<std::string, std::string> movie_failures_;
  std::string current_;                 // the sequence being made, "" when none
  std::set<std::string> forgotten_;     // removed sequences: no more work, no thumbnails
  // The thread's own: thumbnails of each sequence's finished frames, until it is complete.
  struct Thumbnails {
    uint32_t width = 0, height = 0;  // of the frames; 0 until one is read
    size_t count = 0;                // frames the pictures' layout was made for
    std::map<int64_t, Rgb8Image> pictures;
  };
  std::map<std::string, Thumbnails> thumbnails_;
  BackgroundWriter<Request> tasks_{[this](Request& r) { make(r); }};  // last: uses the above
};

}  // namespace rayfarm::master
