#include "master/movie.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

#include <fmt/format.h>

#include "common/util/atomic_file.h"

extern char** environ;

namespace rayfarm::master {
namespace fs = std::filesystem;
namespace {

using Clock = std::chrono::steady_clock;

/// Whether ffmpeg's log says it has no such encoder (the wording differs between versions).
bool lacks_encoder(const fs::path& log) {
  std::ifstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    if (line.find("nknown encoder") != std::string::npos ||
        line.find("ncoder not found") != std::string::npos) {
      return true;
    }
  }
  return false;
}

/// The last non-empty line of a file (ffmpeg's error log), at most 300 characters.
std::string last_line(const fs::path& file) {
  std::ifstream in(file);
  std::string line, last;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  }
  return last.substr(0, 300);
}

class Encoder {
 public:
  Encoder(const MovieSpec& movie, const std::string& codec, const fs::path& output,
          const fs::path& log, Clock::time_point deadline, const std::atomic<bool>& stop)
      : movie_(movie), deadline_(deadline), stop_(stop) {
    const std::string size = fmt::format("{}x{}", movie.width, movie.height);
    const std::string rate = fmt::format("{:.9g}", movie.fps);
    std::vector<std::string> args = {movie.ffmpeg,
                                     "-hide_banner",
                                     "-loglevel",
                                     "error",
                                     "-y",
                                     "-f",
                                     "rawvideo",
                                     "-pix_fmt",
                                     "rgb24",
                                     "-s",
                                     size,
                                     "-framerate",
                                     rate,
                                     "-i",
                                     "pipe:0",
                                     "-vf",
                                     "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                     "-pix_fmt",
                                     "yuv420p",
                                     "-c:v",
                                     codec};
    if (codec == "libx264") {
      args.insert(args.end(), {"-preset", "veryfast", "-crf", "18"});
    } else {
      args.insert(args.end(), {"-q:v", "2"});
    }
    args.insert(args.end(), {"-movflags", "+faststart", "-f", "mp4", output.string()});
    args_ = std::move(args);
    log_ = log;
  }

  /// "" when ffmpeg encoded every frame and exited 0.
  std::string run() {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) return fmt::format("cannot make a pipe: {}", strerror(errno));
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[0], 0);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> argv;
    for (std::string& a : args_) argv.push_back(a.data());
    argv.push_back(nullptr);
    // A group of its own, so that a kill reaches whatever it started too (a wrapper script).
    posix_spawnattr_t attributes;
    posix_spawnattr_init(&attributes);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attributes, 0);
    const int spawned = posix_spawnp(&pid_, argv[0], &actions, &attributes, argv.data(), environ);
    posix_spawnattr_destroy(&attributes);
    posix_spawn_file_actions_destroy(&actions);
    close(fds[0]);
    if (spawned != 0) {
      close(fds[1]);
      return spawned == ENOENT
                 ? "ffmpeg not found (" + movie_.ffmpeg + ")"
                 : fmt::format("cannot start {}: {}", movie_.ffmpeg, strerror(spawned));
    }
    fcntl(fds[1], F_SETFL, O_NONBLOCK);
    std::string why;
    for (size_t i = 0; i < movie_.frames && why.empty() && !broken_; ++i) {
      std::vector<uint8_t> pixels;
      try {
        pixels = movie_.frame(i);
      } catch (const std::exception& e) {
        why = e.what();
        break;
      }
      if (pixels.size() != size_t{movie_.width} * movie_.height * 3) {
        why = fmt::format("frame {} of the movie is not {}x{}", i, movie_.width, movie_.height);
        break;
      }
      why = feed(fds[1], pixels);
    }
    close(fds[1]);
    const std::string ended = wait(!why.empty());
    if (!why.empty()) return why;
    return ended;
  }

 private:
  const MovieSpec& movie_;
  Clock::time_point deadline_;
  const std::atomic<bool>& stop_;
  std::vector<std::string> args_;
  fs::path log_;
  pid_t pid_ = -1;
  bool broken_ = false;  // ffmpeg closed its input

  std::string interrupted() const {
    return stop_ ? "stopped (the master is stopping, or the sequence is being removed)"
                 : "ffmpeg took longer than its time limit";
  }

  std::string feed(int fd, const std::vector<uint8_t>& bytes) {
    size_t done = 0;
    while (done < bytes.size()) {
      if (stop_ || Clock::now() > deadline_) return interrupted();
      pollfd p{fd, POLLOUT, 0};
      if (poll(&p, 1, 200) < 0 && errno != EINTR) return strerror(errno);
      const ssize_t n = write(fd, bytes.data() + done, bytes.size() - done);
      if (n > 0) {
        done += static_cast<size_t>(n);
      } else if (n < 0 && errno == EPIPE) {
        broken_ = true;  // ffmpeg stopped reading: its exit status says why
        return "";
      } else if (n < 0 && errno != EAGAIN && errno != EINTR) {
        return fmt::format("cannot write to ffmpeg: {}", strerror(errno));
      }
    }
    return "";
  }

  /// Waits for ffmpeg (killing it when `kill_now`, past the deadline or when stopping); "" when it
  /// exited 0.
  std::string wait(bool kill_now) {
    int status = 0;
    while (true) {
      const pid_t r = waitpid(pid_, &status, WNOHANG);
      if (r == pid_) break;
      if (r < 0 && errno != EINTR)
        return fmt::format("cannot wait for ffmpeg: {}", strerror(errno));
      if (kill_now || stop_ || Clock::now() > deadline_) {
        ::kill(-pid_, SIGKILL);
        waitpid(pid_, &status, 0);
        return kill_now ? "" : interrupted();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return "";
    const std::string line = last_line(log_);
    return fmt::format("ffmpeg {} {}{}",
                       WIFEXITED(status) ? "exited with status" : "was killed by signal",
                       WIFEXITED(status) ? WEXITSTATUS(status) : WTERMSIG(status),
                       line.empty() ? "" : ": " + line);
  }
};

}  // namespace

std::string write_movie(const fs::path& path, const MovieSpec& movie,
                        std::chrono::seconds time_limit, const std::atomic<bool>& stop) {
  // A broken pipe (ffmpeg gone) is an error of write() on this thread, not a signal.
  sigset_t pipe_signal;
  sigemptyset(&pipe_signal);
  sigaddset(&pipe_signal, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipe_signal, nullptr);
  if (movie.frames == 0 || movie.width == 0 || movie.height == 0) return "no frames";
  const Clock::time_point deadline = Clock::now() + time_limit;
  const fs::path log = path.string() + ".log";
  std::string why;
  for (const char* codec : {"libx264", "mpeg4"}) {
    try {
      write_atomically(path, [&](const fs::path& temporary) {
        why = Encoder(movie, codec, temporary, log, deadline, stop).run();
        if (!why.empty()) throw std::runtime_error(why);
      });
    } catch (const std::exception& e) {
      if (why.empty()) why = e.what();  // the file, not ffmpeg
    }
    // Only an encoder this ffmpeg lacks is worth a second try.
    if (why.empty() || !lacks_encoder(log)) break;
  }
  // A SIGPIPE raised while blocked stays pending on this thread: take it.
  timespec zero{0, 0};
  while (sigtimedwait(&pipe_signal, nullptr, &zero) > 0) {
  }
  std::error_code ec;
  fs::remove(log, ec);  // its last line is in `why`
  return why;
}

}  // namespace rayfarm::master
