#pragma once
// The HTTP endpoint's front door: every request's line and headers are read and measured before
// the HTTP library parses and stores any of them. The library keeps every header it reads, with no
// bound on their count, before a route or a token is looked at; a request of millions of small
// headers would make the master hold gigabytes. Here a connection's bytes pass through a buffer of
// our own: a request whose head (request line and headers, up to the empty line) is larger than
// kMaxHeadBytes, or has more than kMaxHeaderLines headers, or does not arrive whole within
// kHeadDeadline, is answered 431 (or dropped, when it stalls) and the connection closed, without
// the library seeing it. The body stays bounded by the library's payload limit.
#include <chrono>
#include <cstddef>
#include <string_view>

#include <httplib.h>

namespace rayfarm::master {

/// Bounds on a request's head: docs/reliability.md, "HTTP".
inline constexpr size_t kMaxHeadBytes = 64 * 1024;
inline constexpr size_t kMaxHeaderLines = 100;
/// From the request's first byte to its empty line.
inline constexpr std::chrono::seconds kHeadDeadline{10};

/// What the first bytes of a connection's next request are, as far as its head goes.
struct HeadScan {
  enum class Verdict {
    kIncomplete,     ///< no end of the head yet, and within the bounds so far
    kComplete,       ///< the head ends at `bytes` (just past its empty line)
    kTooLarge,       ///< over kMaxHeadBytes before its end
    kTooManyFields,  ///< more than kMaxHeaderLines header lines
  };
  Verdict verdict = Verdict::kIncomplete;
  size_t bytes = 0;  ///< the head's length, when complete
};

/// Reads `data` as the library does: the request line, then header lines, each ending with '\n',
/// up to the first line that is exactly "\r\n". Lines that end with a bare '\n' count as header
/// lines (the library skips them, but still reads them).
HeadScan scan_request_head(std::string_view data, size_t max_bytes = kMaxHeadBytes,
                           size_t max_lines = kMaxHeaderLines);

/// An httplib::Server whose connections pass the checks above before the library reads a request.
/// Keep-alive, timeouts and stop() behave as the library's own: its settings are read from it.
class GuardedHttpServer : public httplib::Server {
 private:
  bool process_and_close_socket(socket_t sock) override;
};

}  // namespace rayfarm::master
