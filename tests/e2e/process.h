#pragma once
// Child processes for end-to-end tests: started with fork/exec, output to a log file, and always
// reaped. A Process still running when it goes out of scope is killed with SIGKILL, so a failing
// test never leaves a master or worker behind; children also die with the test (PR_SET_PDEATHSIG).
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace rayfarm::test {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

class Process {
 public:
  /// Starts argv[0] with `argv`; stdout goes to `out`, stderr to `err` (the same file if equal).
  Process(const std::vector<std::string>& argv, const std::filesystem::path& out,
          const std::filesystem::path& err)
      : log_(err) {
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    const std::string out_path = out.string(), err_path = err.string();
    const pid_t parent = ::getpid();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (::getppid() != parent) ::_exit(127);
      const int fd_out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      const int fd_err = err_path == out_path
                             ? fd_out
                             : ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd_out < 0 || fd_err < 0) ::_exit(126);
      ::dup2(fd_out, STDOUT_FILENO);
      ::dup2(fd_err, STDERR_FILENO);
      const int fd_in = ::open("/dev/null", O_RDONLY);
      if (fd_in >= 0) ::dup2(fd_in, STDIN_FILENO);
      ::execv(args[0], args.data());
      ::_exit(127);
    }
  }
  /// Both streams to one log file.
  Process(const std::vector<std::string>& argv, const std::filesystem::path& log)
      : Process(argv, log, log) {}

  ~Process() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  void signal(int sig) const {
    if (!exited_) ::kill(pid_, sig);
  }
  bool running() {
    poll_exit();
    return !exited_;
  }
  /// Waits at most `timeout` for the process to exit; its exit code (128 + signal when killed).
  std::optional<int> wait(milliseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (!poll_exit() && Clock::now() < deadline) std::this_thread::sleep_for(milliseconds{10});
    if (!exited_) return std::nullopt;
    return code_;
  }
  /// Everything the process wrote to its stderr file so far.
  std::string log() const {
    std::ifstream in(log_, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  int code_ = -1;
  std::filesystem::path log_;

  bool poll_exit() {
    if (exited_) return true;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    return exited_;
  }
};

/// A TCP port on 127.0.0.1 that was free a moment ago (bound to port 0, then released).
inline int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof addr;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    if (fd >= 0) ::close(fd);
    throw std::runtime_error("cannot find a free port");
  }
  ::close(fd);
  return ntohs(addr.sin_port);
}

/// Polls `condition` every 20 ms for at most `timeout`; true as soon as it holds.
inline bool wait_until(const std::function<bool()>& condition, milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(milliseconds{20});
  }
  return condition();
}

/// Occurrences of `needle` in `text`.
inline size_t count_of(const std::string& text, const std::string& needle) {
  size_t n = 0;
  for (size_t pos = text.find(needle); pos != std::string::npos; pos = text.find(needle, pos + 1))
    ++n;
  return n;
}

}  // namespace rayfarm::test
