#pragma once
// Text for people: messages safe to print whatever bytes they quote, and figures (sizes, rates)
// written the same way in the master's log and the command line's output.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace rayfarm {

/// Whether printable() keeps quotes and backslashes (text already quoted, e.g. a JSON dump) or
/// hides them too (text from a peer put inside a log line's quotes).
enum class Quotes { kKeep, kHide };

/// `text` made safe for one message line: bytes outside printable ASCII become '?' (and, with
/// Quotes::kHide, '"' and '\\' too); text longer than `limit` is cut there and marked "...".
std::string printable(std::string_view text, size_t limit = std::string_view::npos,
                      Quotes quotes = Quotes::kKeep);

/// "12.3 MiB", "4.0 KiB" or "17 B".
std::string human_bytes(uint64_t bytes);
/// "12.3 MiB" whatever the size.
std::string mib(uint64_t bytes);
/// "1.25 Msamples/s", "12.5 ksamples/s" or "12 samples/s".
std::string human_rate(double samples_per_second);

}  // namespace rayfarm
