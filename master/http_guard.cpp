#include "master/http_guard.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <mutex>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/util/log.h"
#include "common/util/log_throttle.h"
#include "master/metrics.h"

namespace rayfarm::master {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

/// Bytes asked of the socket at a time; what comes after the current request stays buffered for
/// the next one on the connection.
constexpr size_t kReadChunk = 16 * 1024;
/// After a 431, what the client still sends is read and thrown away for at most this long and
/// this many bytes before the connection is closed, so that the answer reaches it instead of a
/// reset.
constexpr auto kDrainTime = milliseconds{500};
constexpr size_t kDrainBytes = size_t{4} << 20;
/// How often a connection waiting for its next request looks whether the server is stopping.
constexpr auto kStopCheck = milliseconds{100};

/// Waits until `sock` is ready for `events`; false on a timeout or an error.
bool wait_socket(int sock, short events, milliseconds timeout) {
  pollfd p{sock, events, 0};
  for (;;) {
    const int n = ::poll(&p, 1, static_cast<int>(std::max<milliseconds::rep>(0, timeout.count())));
    if (n < 0 && errno == EINTR) continue;
    return n > 0;
  }
}

milliseconds until(Clock::time_point deadline) {
  return std::max(milliseconds{0},
                  std::chrono::duration_cast<milliseconds>(deadline - Clock::now()));
}

void address_of(int sock, bool peer, std::string& ip, int& port) {
  sockaddr_storage addr{};
  socklen_t len = sizeof(addr);
  const int r = peer ? ::getpeername(sock, reinterpret_cast<sockaddr*>(&addr), &len)
                     : ::getsockname(sock, reinterpret_cast<sockaddr*>(&addr), &len);
  if (r != 0) return;
  char host[NI_MAXHOST];
  char serv[NI_MAXSERV];
  if (::getnameinfo(reinterpret_cast<sockaddr*>(&addr), len, host, sizeof(host), serv,
                    sizeof(serv), NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
    ip = host;
    port = std::atoi(serv);
  }
}

/// A connection's socket with a read buffer that lasts from one request to the next: the head
/// of each request is read into it whole (and measured) before the library reads a byte of it.
class BufferedSocketStream final : public httplib::Stream {
 public:
  BufferedSocketStream(int sock, milliseconds read_timeout, milliseconds write_timeout)
      : sock_(sock), read_timeout_(read_timeout), write_timeout_(write_timeout) {}

  bool is_readable() const override {
    return buffered() > 0 || wait_socket(sock_, POLLIN, read_timeout_);
  }
  bool is_writable() const override { return wait_socket(sock_, POLLOUT, write_timeout_); }

  ssize_t read(char* ptr, size_t size) override {
    if (buffered() == 0) {
      if (!wait_socket(sock_, POLLIN, read_timeout_)) return -1;
      const ssize_t n = fill();
      if (n <= 0) return n;
    }
    const size_t n = std::min(size, buffered());
    std::memcpy(ptr, buf_.data() + pos_, n);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }

  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    for (;;) {
      const ssize_t n = ::send(sock_, ptr, size, MSG_NOSIGNAL);
      if (n < 0 && errno == EINTR) continue;
      return n;
    }
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    address_of(sock_, true, ip, port);
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    address_of(sock_, false, ip, port);
  }
  socket_t socket() const override { return sock_; }

  /// Waits up to `timeout` for the next request's first byte, giving up early when `stopping`.
  template <typename Stopping>
  bool wait_for_request(milliseconds timeout, Stopping stopping) const {
    if (buffered() > 0) return true;
    const auto deadline = Clock::now() + timeout;
    while (!stopping()) {
      const auto left = until(deadline);
      if (wait_socket(sock_, POLLIN, std::min(left, milliseconds{kStopCheck}))) return true;
      if (left <= kStopCheck) return false;
    }
    return false;
  }

  /// Reads until the buffer holds the next request's whole head or it breaks a bound; kIncomplete
  /// when the peer closed or stalled past kHeadDeadline.
  HeadScan read_head() {
    const auto deadline = Clock::now() + kHeadDeadline;
    for (;;) {
      const HeadScan scan =
          scan_request_head(std::string_view(buf_).substr(pos_));
      if (scan.verdict != HeadScan::Verdict::kIncomplete) return scan;
      if (!wait_socket(sock_, POLLIN, until(deadline))) return scan;
      if (fill() <= 0) return scan;
    }
  }

  /// Reads and discards what the peer still sends, within the drain bounds.
  void drain() {
    const auto deadline = Clock::now() + kDrainTime;
    size_t drained = 0;
    char sink[kReadChunk];
    while (drained < kDrainBytes && wait_socket(sock_, POLLIN, until(deadline))) {
      const ssize_t n = ::recv(sock_, sink, sizeof(sink), 0);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      drained += static_cast<size_t>(n);
    }
  }

 private:
  size_t buffered() const { return buf_.size() - pos_; }

  /// One recv() appended to the buffer (read bytes dropped first): its count, 0 at the end of the
  /// stream, -1 on an error.
  ssize_t fill() {
    if (pos_ > 0) {
      buf_.erase(0, pos_);
      pos_ = 0;
    }
    const size_t old = buf_.size();
    buf_.resize(old + kReadChunk);
    ssize_t n;
    do {
      n = ::recv(sock_, buf_.data() + old, kReadChunk, 0);
    } while (n < 0 && errno == EINTR);
    buf_.resize(old + static_cast<size_t>(std::max<ssize_t>(n, 0)));
    return n;
  }

  int sock_;
  milliseconds read_timeout_, write_timeout_;
  std::string buf_;
  size_t pos_ = 0;
};

/// The 431 answer, written by hand: the library never saw the request.
void answer_too_large(BufferedSocketStream& strm, const HeadScan& scan) {
  const std::string why =
      scan.verdict == HeadScan::Verdict::kTooManyFields
          ? fmt::format("request refused: more than {} header lines", kMaxHeaderLines)
          : fmt::format("request refused: its request line and headers exceed {} KiB",
                        kMaxHeadBytes / 1024);
  const std::string body = nlohmann::json{{"error", why}}.dump();
  const std::string response = fmt::format(
      "HTTP/1.1 431 Request Header Fields Too Large\r\n"
      "Content-Type: application/json\r\n"
      "Content-Length: {}\r\n"
      "Connection: close\r\n"
      "X-Content-Type-Options: nosniff\r\n"
      "\r\n{}",
      body.size(), body);
  size_t sent = 0;
  while (sent < response.size()) {
    const ssize_t n = strm.write(response.data() + sent, response.size() - sent);
    if (n <= 0) break;
    sent += static_cast<size_t>(n);
  }
  metrics().http_responses.add("431");
  metrics().refusals.add("http_headers");
  static std::mutex mutex;
  static LogThrottle throttle(std::chrono::seconds{10});
  std::string ip;
  int port = 0;
  strm.get_remote_ip_and_port(ip, port);
  std::lock_guard lock(mutex);
  const LogThrottle::Verdict verdict = throttle.occur();
  if (verdict.log) {
    get_logger("master")->warn("HTTP: {} from {}{}", why, ip.empty() ? "an unknown peer" : ip,
                               LogThrottle::suffix(verdict));
  }
  ::shutdown(strm.socket(), SHUT_WR);
  strm.drain();
}

}  // namespace

HeadScan scan_request_head(std::string_view data, size_t max_bytes, size_t max_lines) {
  HeadScan scan;
  size_t start = 0;
  size_t lines = 0;  // after the request line
  for (;;) {
    const size_t end = data.find('\n', start);
    const size_t limit = std::min(data.size(), max_bytes);
    if (end == std::string_view::npos || end >= limit) {
      scan.verdict = data.size() >= max_bytes ? HeadScan::Verdict::kTooLarge
                                              : HeadScan::Verdict::kIncomplete;
      return scan;
    }
    const std::string_view line = data.substr(start, end + 1 - start);
    if (start > 0 && line == "\r\n") {
      scan.verdict = HeadScan::Verdict::kComplete;
      scan.bytes = end + 1;
      return scan;
    }
    if (start > 0 && ++lines > max_lines) {
      scan.verdict = HeadScan::Verdict::kTooManyFields;
      return scan;
    }
    start = end + 1;
  }
}

bool GuardedHttpServer::process_and_close_socket(socket_t sock) {
  using std::chrono::seconds;
  using std::chrono::microseconds;
  const auto read_timeout = std::chrono::duration_cast<milliseconds>(
      seconds{read_timeout_sec_} + microseconds{read_timeout_usec_});
  const auto write_timeout = std::chrono::duration_cast<milliseconds>(
      seconds{write_timeout_sec_} + microseconds{write_timeout_usec_});
  BufferedSocketStream strm(sock, read_timeout, write_timeout);
  const auto stopping = [this] { return svr_sock_ == INVALID_SOCKET; };
  bool ok = false;
  // The library's keep-alive loop: at most keep_alive_max_count_ requests on one connection,
  // each awaited for keep_alive_timeout_sec_.
  for (size_t left = std::max<size_t>(keep_alive_max_count_, 1); left > 0; --left) {
    if (stopping() || !strm.wait_for_request(seconds{keep_alive_timeout_sec_}, stopping)) break;
    const HeadScan head = strm.read_head();
    if (head.verdict == HeadScan::Verdict::kIncomplete) break;  // closed, or stalled: dropped
    if (head.verdict != HeadScan::Verdict::kComplete) {
      answer_too_large(strm, head);
      ok = false;
      break;
    }
    bool connection_closed = false;
    ok = process_request(strm, /*close_connection=*/left == 1, connection_closed, nullptr);
    if (!ok || connection_closed) break;
  }
  ::shutdown(sock, SHUT_RDWR);
  ::close(sock);
  return ok;
}

}  // namespace rayfarm::master
