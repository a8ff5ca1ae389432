#include "master/sequence_previews.h"

#include <chrono>

#include "common/image/png.h"
#include "common/util/log.h"
#include "master/movie.h"

namespace rayfarm::master {
namespace fs = std::filesystem;

namespace {
std::shared_ptr<spdlog::logger> log_previews() { return get_logger("jobs"); }
}  // namespace

SequencePreviews::SequencePreviews(std::string ffmpeg) : ffmpeg_(std::move(ffmpeg)) {}

SequencePreviews::~SequencePreviews() {
  stopping_ = true;
  abort_current_ = true;
}

void SequencePreviews::submit(Request request) {
  const std::string id = request.sequence;
  {
    std::lock_guard lock(mutex_);
    forgotten_.erase(id);  // an id given again after its sequence was removed
  }
  tasks_.submit(std::move(request), [&](const Request& waiting) { return waiting.sequence == id; });
}

void SequencePreviews::forget(const std::string& sequence) {
  tasks_.discard([&](const Request& waiting) { return waiting.sequence == sequence; });
  std::unique_lock lock(mutex_);
  if (current_ == sequence) abort_current_ = true;
  made_.wait(lock, [&] { return current_ != sequence; });
  movie_failures_.erase(sequence);
  // A request taken off the queue but not started yet sees this and does nothing.
  forgotten_.insert(sequence);
}

std::string SequencePreviews::movie_failure(const std::string& sequence) const {
  std::lock_guard lock(mutex_);
  auto it = movie_failures_.find(sequence);
  return it == movie_failures_.end() ? std::string() : it->second;
}

void SequencePreviews::make(Request& request) {
  bool gone = false;
  {
    std::lock_guard lock(mutex_);
    for (const std::string& id : forgotten_) thumbnails_.erase(id);
    gone = forgotten_.count(request.sequence) > 0;
    if (!gone) current_ = request.sequence;
    abort_current_ = stopping_.load();
  }
  if (gone) return;  // removed meanwhile: its folder is going
  if (!request.frames.empty()) {
    if (request.sheet) make_sheet(request);
    if (request.movie && !abort_current_) make_movie(request);
    bool complete = true;
    for (const Frame& f : request.frames) complete = complete && f.done;
    if (complete) thumbnails_.erase(request.sequence);  // its sheet changes no more
  }
  std::lock_guard lock(mutex_);
  current_.clear();
  made_.notify_all();
}

void SequencePreviews::make_sheet(const Request& request) {
  Thumbnails& thumbs = thumbnails_[request.sequence];
  if (thumbs.count != request.frames.size()) {
    thumbs = Thumbnails{};  // made for another layout
    thumbs.count = request.frames.size();
  }
  try {
    std::vector<SheetCell> cells;
    for (const Frame& f : request.frames) {
      cells.push_back({f.frame, nullptr});
      if (!f.done) continue;
      auto it = thumbs.pictures.find(f.frame);
      if (it == thumbs.pictures.end()) {
        const Image image = read_exr(f.exr, ExrExpect{.rgb_only = true});
        if (thumbs.width == 0) {
          thumbs.width = image.width;
          thumbs.height = image.height;
        } else if (image.width != thumbs.width || image.height != thumbs.height) {
          throw std::runtime_error(fmt::format("frame {} is {}x{}, another {}x{}", f.frame,
                                               image.width, image.height, thumbs.width,
                                               thumbs.height));
        }
        const SheetLayout layout = sheet_layout(request.frames.size(), image.width, image.height);
        it = thumbs.pictures
                 .emplace(f.frame, thumbnail(image, layout.cell_width, layout.cell_height))
                 .first;
      }
      cells.back().picture = &it->second;
    }
    if (thumbs.width == 0) return;  // nothing finished yet
    const SheetLayout layout = sheet_layout(request.frames.size(), thumbs.width, thumbs.height);
    write_png_rgb8(request.dir / kSheetName, contact_sheet(layout, cells).rgb, layout.width(),
                   layout.height());
  } catch (const std::exception& e) {
    log_previews()->error("sequence {}: cannot write its contact sheet: {}", request.sequence,
                          e.what());
  }
}

void SequencePreviews::make_movie(const Request& request) {
  std::string why;
  if (ffmpeg_.empty()) {
    why = "movies are turned off (--ffmpeg '')";
  } else {
    MovieSpec movie;
    movie.ffmpeg = ffmpeg_;
    movie.fps = request.fps;
    movie.frames = request.frames.size();
    // The size comes from the first frame; every frame is read when its turn comes.
    try {
      const Image first = read_exr(request.frames.front().exr, ExrExpect{.rgb_only = true});
      movie.width = first.width;
      movie.height = first.height;
      movie.frame = [&](size_t i) {
        const Image image = read_exr(request.frames[i].exr, ExrExpect{.rgb_only = true});
        if (image.width != movie.width || image.height != movie.height) {
          throw std::runtime_error(fmt::format("frame {} is {}x{}, the first {}x{}",
                                               request.frames[i].frame, image.width, image.height,
                                               movie.width, movie.height));
        }
        return preview_pixels(image);
      };
      // Generous: a minute, and a second per frame.
      const auto limit = std::chrono::seconds(60 + movie.frames);
      why = write_movie(request.dir / kMovieName, movie, limit, abort_current_);
    } catch (const std::exception& e) {
      why = e.what();
    }
  }
  if (why.empty()) {
    log_previews()->info("sequence {}: movie {} ({} frames at {:g} fps)", request.sequence,
                         (request.dir / kMovieName).string(), request.frames.size(), request.fps);
  } else if (!abort_current_) {
    log_previews()->warn("sequence {}: no movie: {}{}", request.sequence, why,
                         why.find("not found") != std::string::npos
                             ? " (install Debian's ffmpeg on the master to get one; the "
                               "frames and the contact sheet are there)"
                             : "");
  }
  std::lock_guard lock(mutex_);
  if (why.empty()) {
    movie_failures_.erase(request.sequence);
  } else {
    movie_failures_[request.sequence] = why;
  }
}

}  // namespace rayfarm::master
