#pragma once
// A job's own log: what happened to it, from the master's side (accepted, started, a unit that
// failed and the worker's words for it, a worker blocked or lost, paused, resumed, a storage
// error, how it ended). Kept in its record (job.json) so that it outlives the master, and shown
// by `rayfarm status JOB --detail` and the page's job view. Bounded: the latest kMaxLines, each
// at most kMaxText characters; what was dropped is counted.
#include <cstdint>
#include <string>
#include <vector>

#include "common/util/utf8.h"

namespace rayfarm::master {

struct JobLogLine {
  int64_t unix_ms = 0;
  std::string level;  ///< "info", "warning" or "error"
  std::string text;
  bool operator==(const JobLogLine&) const = default;
};

struct JobLog {
  static constexpr size_t kMaxLines = 40;
  static constexpr size_t kMaxText = 600;
  /// A sequence's frame keeps less: a sequence may have 100,000 of them.
  static constexpr size_t kMaxFrameLines = 6;
  static constexpr size_t kMaxFrameText = 200;

  std::vector<JobLogLine> lines;  ///< oldest first
  uint32_t left_out = 0;          ///< earlier lines dropped

  /// Adds a line, keeping the latest `max_lines` of at most `max_text` bytes each. The text is
  /// made safe first: a byte that is not part of well-formed UTF-8, and a control character,
  /// becomes '?' (job.json and the wire hold UTF-8 only; a terminal takes no escapes from here).
  void add(int64_t unix_ms, std::string level, std::string text, size_t max_lines = kMaxLines,
           size_t max_text = kMaxText) {
    text = clean(text);
    if (text.size() > max_text) {
      // Cut on a character's first byte, so that the line stays UTF-8.
      size_t cut = max_text - 3;
      while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;
      text = text.substr(0, cut) + "...";
    }
    while (!lines.empty() && lines.size() >= max_lines) {
      lines.erase(lines.begin());
      ++left_out;
    }
    lines.push_back(JobLogLine{unix_ms, clean(level), std::move(text)});
    ++version;
  }
  /// Counts add(): a record whose log changed since it was saved is saved again.
  uint64_t version = 0;

  bool operator==(const JobLog& other) const {
    return lines == other.lines && left_out == other.left_out;
  }

  /// `text` with every byte outside well-formed UTF-8, and every control character, as '?'.
  static std::string clean(const std::string& text) {
    std::string out;
    out.reserve(text.size());
    for (size_t i = 0; i < text.size();) {
      const auto c = static_cast<unsigned char>(text[i]);
      const size_t length = utf8_length_at(text, i);
      if (length == 0 || c < 0x20 || c == 0x7F) {
        out += '?';
        ++i;
        continue;
      }
      out.append(text, i, length);
      i += length;
    }
    return out;
  }
};

}  // namespace rayfarm::master
