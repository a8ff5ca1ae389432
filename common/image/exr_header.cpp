#include "common/image/exr_header.h"

#include <string>

namespace rayfarm {

std::optional<std::pair<int64_t, int64_t>> peek_exr_data_window(std::string_view head) {
  auto read_i32 = [&](size_t at) {
    uint32_t v = 0;
    for (int b = 3; b >= 0; --b) v = (v << 8) | static_cast<unsigned char>(head[at + b]);
    return static_cast<int32_t>(v);
  };
  if (head.size() < 8 || read_i32(0) != 20000630) return std::nullopt;  // the EXR magic number
  size_t at = 8;
  auto read_name = [&](std::string& out) {
    const size_t end = head.find('\0', at);
    if (end == std::string_view::npos || end - at > 255) return false;
    out = std::string(head.substr(at, end - at));
    at = end + 1;
    return true;
  };
  std::optional<std::pair<int64_t, int64_t>> window;
  for (;;) {
    std::string name, type;
    if (!read_name(name)) return std::nullopt;
    if (name.empty()) return window;  // the end of the header
    if (!read_name(type) || at + 4 > head.size()) return std::nullopt;
    const int32_t size = read_i32(at);
    at += 4;
    if (size < 0 || at + static_cast<size_t>(size) > head.size()) return std::nullopt;
    if (name == "dataWindow") {
      if (type != "box2i" || size != 16) return std::nullopt;
      const int64_t x0 = read_i32(at), y0 = read_i32(at + 4), x1 = read_i32(at + 8),
                    y1 = read_i32(at + 12);
      window = std::pair{x1 - x0 + 1, y1 - y0 + 1};
    }
    at += static_cast<size_t>(size);
  }
}

}  // namespace rayfarm
