#pragma once
// The line-based formats' common ground (OBJ, MTL): places "FILE:LINE" for messages, line
// splitting with the bytes of every line checked, words, and numbers within the format's range.
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/scene/scene_files.h"

namespace rayfarm::scene_text {

/// A place in a file, printed "FILE:LINE" (or "FILE" when the line is unknown).
struct Where {
  std::string file;
  size_t line = 0;

  std::string str() const { return line == 0 ? file : file + ":" + std::to_string(line); }
  [[noreturn]] void fail(const std::string& what) const { throw SceneError(str() + ": " + what); }
  std::string message(const std::string& what) const { return str() + ": " + what; }
};

/// Quotes a name taken from a file, shortened so that a message stays readable.
std::string in_quotes(std::string_view name);

/// Rejects bytes that no text line may hold: broken UTF-8, NUL, a carriage return mid-line.
void check_line_bytes(const Where& at, std::string_view line);

/// Calls visit(line_number, line) for every line, without its "\n" or "\r\n", bytes checked.
template <class Visit>
void for_each_line(const std::string& text, const std::string& file, Visit&& visit) {
  size_t start = 0;
  size_t number = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const Where at{file, ++number};
    check_line_bytes(at, line);
    visit(at, line);
    start = end + 1;
  }
}

/// The words of `line`, split at blanks and tabs.
std::vector<std::string_view> split_words(std::string_view line);

/// The text after the first word, without surrounding blanks ("newmtl my name" -> "my name").
std::string_view rest_after_keyword(std::string_view line, std::string_view keyword);

/// A finite decimal number no larger than kMaxAbsNumber in magnitude, or nullopt.
std::optional<double> parse_number(std::string_view word);

/// Checks that words[1..] are `count` numbers (any count in [min, max]).
void check_numbers(const Where& at, const std::vector<std::string_view>& words, size_t min,
                   size_t max, const std::string& expected);

}  // namespace rayfarm::scene_text
