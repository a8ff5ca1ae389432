#pragma once
// Well-formed UTF-8, as JSON and proto3 strings require it: what the readers of text files check
// (common/scene/text_lines.cpp) and what the master's job log keeps (master/job_log.h).
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace rayfarm {

/// Length (1 to 4) of the well-formed UTF-8 character that starts at s[i]; 0 when none does
/// there: a stray continuation byte, an overlong form, a surrogate, a code point past U+10FFFF,
/// or a character cut short by the end of `s`.
inline size_t utf8_length_at(std::string_view s, size_t i) {
  const auto lead = static_cast<unsigned char>(s[i]);
  if (lead < 0x80) return 1;
  size_t length = 0;
  uint32_t code = 0, smallest = 0;
  if ((lead & 0xE0) == 0xC0) {
    length = 2, code = lead & 0x1Fu, smallest = 0x80;
  } else if ((lead & 0xF0) == 0xE0) {
    length = 3, code = lead & 0x0Fu, smallest = 0x800;
  } else if ((lead & 0xF8) == 0xF0) {
    length = 4, code = lead & 0x07u, smallest = 0x10000;
  } else {
    return 0;
  }
  if (i + length > s.size()) return 0;
  for (size_t k = 1; k < length; ++k) {
    const auto next = static_cast<unsigned char>(s[i + k]);
    if ((next & 0xC0) != 0x80) return 0;
    code = (code << 6) | (next & 0x3Fu);
  }
  if (code < smallest || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return length;
}

/// Offset of the first byte that does not belong to well-formed UTF-8, or npos.
inline size_t invalid_utf8_at(std::string_view s) {
  for (size_t i = 0; i < s.size();) {
    const size_t length = utf8_length_at(s, i);
    if (length == 0) return i;
    i += length;
  }
  return std::string_view::npos;
}

}  // namespace rayfarm
