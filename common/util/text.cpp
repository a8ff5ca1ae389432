#include "common/util/text.h"

#include <fmt/format.h>

namespace rayfarm {

std::string printable(std::string_view text, size_t limit, Quotes quotes) {
  std::string out;
  for (size_t i = 0; i < text.size() && i < limit; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    const bool safe = c >= 0x20 && c < 0x7f && (quotes == Quotes::kKeep || (c != '"' && c != '\\'));
    out.push_back(safe ? static_cast<char>(c) : '?');
  }
  if (text.size() > limit) out += "...";
  return out;
}

std::string human_bytes(uint64_t bytes) {
  if (bytes >= (uint64_t{1} << 20)) return mib(bytes);
  if (bytes >= 1024) return fmt::format("{:.1f} KiB", bytes / 1024.0);
  return fmt::format("{} B", bytes);
}

std::string mib(uint64_t bytes) { return fmt::format("{:.1f} MiB", bytes / 1048576.0); }

std::string human_rate(double samples_per_second) {
  if (samples_per_second >= 1e6) return fmt::format("{:.2f} Msamples/s", samples_per_second / 1e6);
  if (samples_per_second >= 1e3) return fmt::format("{:.1f} ksamples/s", samples_per_second / 1e3);
  return fmt::format("{:.0f} samples/s", samples_per_second);
}

}  // namespace rayfarm
