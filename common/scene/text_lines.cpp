#include "common/scene/text_lines.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <system_error>

#include "common/limits.h"
#include "common/util/utf8.h"

namespace rayfarm::scene_text {
namespace {

constexpr size_t kMaxNameInMessage = 60;

}  // namespace

/// Quotes a name taken from a file, shortened so that a message stays readable.
std::string in_quotes(std::string_view name) {
  std::string out = "\"";
  // Cut on a character's first byte: a message must stay UTF-8 (the wire, JSON).
  size_t cut = std::min(name.size(), kMaxNameInMessage);
  while (cut > 0 && cut < name.size() && (static_cast<unsigned char>(name[cut]) & 0xC0) == 0x80) {
    --cut;
  }
  out.append(name.substr(0, cut));
  if (name.size() > cut) out += "...";
  out += '"';
  return out;
}

/// Rejects bytes that no text line may hold: broken UTF-8, NUL, a carriage return mid-line.
void check_line_bytes(const Where& at, std::string_view line) {
  if (const size_t bad = invalid_utf8_at(line); bad != std::string_view::npos) {
    char hex[8];
    std::snprintf(hex, sizeof hex, "0x%02X", static_cast<unsigned char>(line[bad]));
    at.fail("invalid UTF-8 byte " + std::string(hex) + " at column " + std::to_string(bad + 1));
  }
  if (const size_t nul = line.find('\0'); nul != std::string_view::npos) {
    at.fail("NUL byte at column " + std::to_string(nul + 1));
  }
  if (line.find('\r') != std::string_view::npos) at.fail("carriage return inside a line");
}

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

/// The text after the first word, without surrounding blanks ("newmtl my name" -> "my name").
std::string_view rest_after_keyword(std::string_view line, std::string_view keyword) {
  std::string_view rest = line.substr(line.find(keyword) + keyword.size());
  const size_t first = rest.find_first_not_of(" \t");
  if (first == std::string_view::npos) return {};
  rest = rest.substr(first);
  return rest.substr(0, rest.find_last_not_of(" \t") + 1);
}

/// A finite decimal number no larger than 1e30 in magnitude, or nullopt.
std::optional<double> parse_number(std::string_view word) {
  if (!word.empty() && word.front() == '+') word.remove_prefix(1);
  if (word.empty() || word.front() == '+') return std::nullopt;
  double value = 0.0;
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (error != std::errc() || end != word.data() + word.size()) return std::nullopt;
  if (!std::isfinite(value) || std::abs(value) > kMaxAbsNumber) return std::nullopt;
  return value;
}

/// Checks that words[1..] are `count` numbers (any count in [min, max]).
void check_numbers(const Where& at, const std::vector<std::string_view>& words, size_t min,
                   size_t max, const std::string& expected) {
  const size_t count = words.size() - 1;
  if (count < min || count > max) {
    at.fail(std::string(words[0]) + ": expected " + expected + ", got " + std::to_string(count) +
            " value(s)");
  }
  for (size_t i = 1; i < words.size(); ++i) {
    if (!parse_number(words[i])) {
      at.fail(std::string(words[0]) + ": " + in_quotes(words[i]) +
              " is not a finite number of magnitude at most 1e30");
    }
  }
}

}  // namespace rayfarm::scene_text
