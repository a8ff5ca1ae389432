#pragma once
// A job's own log: what happened to it, from the master's side (accepted, started, a unit that
// failed and the worker's words for it, a worker blocked or lost, paused, resumed, a storage
// error, how it ended). Kept in its record (job.json) so that it outlives the master, and shown
// by `rayfarm status JOB --detail` and the page's job view. Bounded: the latest kMaxLines, each
// at most kMaxText characters; what was dropped is counted.
#include <cstdint>
#include <string>
#include <vector>

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

  std::vector<JobLogLine> lines;  ///< oldest first
  uint32_t left_out = 0;          ///< earlier lines dropped

  void add(int64_t unix_ms, std::string level, std::string text) {
    if (text.size() > kMaxText) {
      // Cut on a character's first byte, so that the line stays UTF-8 (job.json, the wire).
      size_t cut = kMaxText - 3;
      while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;
      text = text.substr(0, cut) + "...";
    }
    if (lines.size() >= kMaxLines) {
      lines.erase(lines.begin());
      ++left_out;
    }
    lines.push_back(JobLogLine{unix_ms, std::move(level), std::move(text)});
  }
  bool operator==(const JobLog&) const = default;
};

}  // namespace rayfarm::master
