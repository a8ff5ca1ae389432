#include "common/image/exr_header.h"

namespace rayfarm {
namespace {

int32_t read_i32(std::string_view bytes, size_t at) {
  uint32_t v = 0;
  for (int b = 3; b >= 0; --b) v = (v << 8) | static_cast<unsigned char>(bytes[at + b]);
  return static_cast<int32_t>(v);
}

}  // namespace

std::optional<std::vector<ExrAttribute>> peek_exr_attributes(std::string_view head) {
  if (head.size() < 8 || read_i32(head, 0) != 20000630) return std::nullopt;  // the magic number
  size_t at = 8;
  auto read_name = [&](std::string_view& out) {
    const size_t end = head.find('\0', at);
    if (end == std::string_view::npos || end - at > 255) return false;
    out = head.substr(at, end - at);
    at = end + 1;
    return true;
  };
  std::vector<ExrAttribute> out;
  for (;;) {
    ExrAttribute a;
    if (!read_name(a.name)) return std::nullopt;
    if (a.name.empty()) return out;  // the end of the header
    if (!read_name(a.type) || at + 4 > head.size()) return std::nullopt;
    const int32_t size = read_i32(head, at);
    at += 4;
    if (size < 0 || at + static_cast<size_t>(size) > head.size()) return std::nullopt;
    a.value = head.substr(at, static_cast<size_t>(size));
    at += static_cast<size_t>(size);
    out.push_back(a);
  }
}

std::optional<std::pair<int64_t, int64_t>> peek_exr_data_window(std::string_view head) {
  const auto attributes = peek_exr_attributes(head);
  if (!attributes) return std::nullopt;
  std::optional<std::pair<int64_t, int64_t>> window;
  for (const ExrAttribute& a : *attributes) {
    if (a.name != "dataWindow") continue;
    if (a.type != "box2i" || a.value.size() != 16) return std::nullopt;
    const int64_t x0 = read_i32(a.value, 0), y0 = read_i32(a.value, 4),
                  x1 = read_i32(a.value, 8), y1 = read_i32(a.value, 12);
    window = std::pair{x1 - x0 + 1, y1 - y0 + 1};
  }
  return window;
}

}  // namespace rayfarm
