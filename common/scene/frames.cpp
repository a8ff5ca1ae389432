#include "common/scene/frames.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
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

bool has_frame_pattern(const std::string& file_name) {
  return file_name.find('#') != std::string::npos || file_name.find('%') != std::string::npos;
}

std::string substitute_frame(const std::string& file_name, int64_t frame) {
  const auto padded = [frame](size_t width) {
    char digits[32];
    std::snprintf(digits, sizeof digits, "%0*lld", int(std::min<size_t>(width, 12)),
                  static_cast<long long>(frame));
    return std::string(digits);
  };
  std::string name = file_name;
  if (const size_t hash = name.find('#'); hash != std::string::npos) {
    size_t end = hash;
    while (end < name.size() && name[end] == '#') ++end;
    name.replace(hash, end - hash, padded(end - hash));
  } else if (const size_t pct = name.find('%'); pct != std::string::npos) {
    size_t at = pct + 1, width = 0;
    while (at < name.size() && std::isdigit(static_cast<unsigned char>(name[at])) != 0) {
      width = std::min<size_t>(width * 10 + size_t(name[at] - '0'), 12);
      ++at;
    }
    if (at >= name.size() || name[at] != 'd') {
      throw std::invalid_argument("a '%' in the name must be a frame number, %d or %04d");
    }
    name.replace(pct, at + 1 - pct, padded(width));
  }
  return name;
}

}  // namespace rayfarm
