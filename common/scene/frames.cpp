#include "common/scene/frames.h"

#include <cstdlib>
#include <string_view>

namespace rayfarm {

namespace {

/// Reads an optionally negative integer at `at`; nullopt when there is none or it is too large.
std::optional<int64_t> read_int(std::string_view text, size_t& at) {
  const size_t start = at;
  bool negative = false;
  if (at < text.size() && text[at] == '-') {
    negative = true;
    ++at;
  }
  int64_t value = 0;
  size_t digits = 0;
  while (at < text.size() && text[at] >= '0' && text[at] <= '9') {
    value = value * 10 + (text[at] - '0');
    ++at;
    if (++digits > 10) return std::nullopt;
  }
  if (digits == 0) {
    at = start;
    return std::nullopt;
  }
  return negative ? -value : value;
}

}  // namespace

std::optional<FrameList> parse_frame_list(const std::string& text, std::string* why) {
  const auto fail = [&](const std::string& what) -> std::optional<FrameList> {
    if (why) *why = what;
    return std::nullopt;
  };
  const std::string expected = "expected A, A-B or A-B:STEP (frame numbers), got \"" + text + "\"";
  size_t at = 0;
  const auto first = read_int(text, at);
  if (!first) return fail(expected);
  FrameList list{*first, *first, 1};
  if (at < text.size() && text[at] == '-') {
    ++at;
    const auto last = read_int(text, at);
    if (!last) return fail(expected);
    list.last = *last;
  }
  if (at < text.size() && text[at] == ':') {
    ++at;
    const auto step = read_int(text, at);
    if (!step) return fail(expected);
    if (*step < 1) return fail("the step of \"" + text + "\" must be at least 1");
    list.step = *step;
  }
  if (at != text.size()) return fail(expected);
  if (std::abs(list.first) > kMaxFrameNumber || std::abs(list.last) > kMaxFrameNumber) {
    return fail("frame numbers of \"" + text + "\" must be within +-1000000000");
  }
  if (list.last < list.first) {
    return fail("the range \"" + text + "\" is reversed: its last frame comes before its first");
  }
  list.last = list.first + (list.last - list.first) / list.step * list.step;
  return list;
}

std::string frame_list_name(const FrameList& frames) {
  if (frames.first == frames.last) return std::to_string(frames.first);
  std::string out = std::to_string(frames.first) + "-" + std::to_string(frames.last);
  if (frames.step != 1) out += ":" + std::to_string(frames.step);
  return out;
}

}  // namespace rayfarm
