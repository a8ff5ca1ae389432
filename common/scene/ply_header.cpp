// PLY headers. The header is text even in a binary file, so its lines are checked as text lines
// are elsewhere (text_lines.h), and it ends at the line "end_header": the body's first byte is the
// one after that line's "\n".
#include "common/scene/ply_header.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <system_error>

#include "common/scene/text_lines.h"

namespace rayfarm::ply {
using scene_text::in_quotes;
using scene_text::Where;

namespace {

struct TypeInfo {
  Type type;
  const char* name;
  const char* other_name;
  size_t bytes;
  long long min, max;  ///< the range of an integer type
};

// Most properties of one element.
constexpr size_t kMaxPlyProperties = 256;

constexpr std::array<TypeInfo, 8> kTypes{{
    {Type::kInt8, "char", "int8", 1, -128, 127},
    {Type::kUint8, "uchar", "uint8", 1, 0, 255},
    {Type::kInt16, "short", "int16", 2, -32768, 32767},
    {Type::kUint16, "ushort", "uint16", 2, 0, 65535},
    {Type::kInt32, "int", "int32", 4, -2147483648LL, 2147483647LL},
    {Type::kUint32, "uint", "uint32", 4, 0, 4294967295LL},
    {Type::kFloat32, "float", "float32", 4, 0, 0},
    {Type::kFloat64, "double", "float64", 8, 0, 0},
}};

const TypeInfo& info(Type type) { return kTypes[static_cast<size_t>(type)]; }

Type parse_type(const Where& at, std::string_view word) {
  for (const TypeInfo& t : kTypes) {
    if (word == t.name || word == t.other_name) return t.type;
  }
  at.fail("unknown property type " + in_quotes(word) +
          "; expected one of char, uchar, short, ushort, int, uint, float, double (or int8, "
          "uint8, int16, uint16, int32, uint32, float32, float64)");
}

/// Reads the header's lines after the first ("ply"), one statement each.
class HeaderReader {
 public:
  explicit HeaderReader(Header* header) : header_(*header) {}

  /// Returns true at end_header.
  bool statement(const Where& at, const std::vector<std::string_view>& words) {
    if (words.empty()) return false;
    const std::string_view keyword = words[0];
    if (keyword == "comment" || keyword == "obj_info") return false;
    if (keyword == "format") {
      format(at, words);
    } else if (keyword == "element") {
      element(at, words);
    } else if (keyword == "property") {
      property(at, words);
    } else if (keyword == "end_header") {
      if (words.size() != 1) at.fail("end_header: unexpected text after it");
      require_format(at, "end_header");
      return true;
    } else {
      at.fail("unknown header line " + in_quotes(keyword) +
              "; expected comment, obj_info, format, element, property or end_header");
    }
    return false;
  }

 private:
  void format(const Where& at, const std::vector<std::string_view>& words) {
    if (has_format_) at.fail("a second format line");
    if (words.size() != 3) {
      at.fail(
          "format: expected \"format ascii 1.0\", \"format binary_little_endian 1.0\" or "
          "\"format binary_big_endian 1.0\"");
    }
    if (words[1] == "ascii") {
      header_.format = Format::kAscii;
    } else if (words[1] == "binary_little_endian") {
      header_.format = Format::kBinaryLittleEndian;
    } else if (words[1] == "binary_big_endian") {
      header_.format = Format::kBinaryBigEndian;
    } else {
      at.fail("unknown format " + in_quotes(words[1]) +
              "; expected ascii, binary_little_endian or binary_big_endian");
    }
    const auto version = scene_text::parse_number(words[2]);
    if (!version || *version != 1.0) {
      at.fail("format version " + in_quotes(words[2]) + " is not supported; only 1.0 is");
    }
    has_format_ = true;
  }

  void require_format(const Where& at, const char* what) const {
    if (!has_format_) {
      at.fail(std::string(what) +
              " before any format line; the header must say \"format ascii 1.0\", \"format "
              "binary_little_endian 1.0\" or \"format binary_big_endian 1.0\" first");
    }
  }

  void element(const Where& at, const std::vector<std::string_view>& words) {
    require_format(at, "element");
    if (words.size() != 3) at.fail("element: expected \"element NAME COUNT\"");
    uint64_t count = 0;
    const std::string_view n = words[2];
    const auto [end, error] = std::from_chars(n.data(), n.data() + n.size(), count);
    if (error != std::errc() || end != n.data() + n.size()) {
      at.fail("element " + in_quotes(words[1]) + ": count " + in_quotes(n) +
              " is not a non-negative integer below 2^64");
    }
    header_.elements.push_back({std::string(words[1]), count, at.line, {}});
  }

  void property(const Where& at, const std::vector<std::string_view>& words) {
    if (header_.elements.empty()) at.fail("property before any element line");
    Property p;
    p.line = at.line;
    if (words.size() >= 2 && words[1] == "list") {
      if (words.size() != 5)
        at.fail("property list: expected \"property list COUNT_TYPE ITEM_TYPE NAME\"");
      p.is_list = true;
      p.count_type = parse_type(at, words[2]);
      if (!is_integer(p.count_type)) {
        at.fail("property list " + in_quotes(words[4]) + ": its length type " +
                in_quotes(words[2]) + " is not an integer type");
      }
      p.type = parse_type(at, words[3]);
      p.name = std::string(words[4]);
    } else {
      if (words.size() != 3) at.fail("property: expected \"property TYPE NAME\"");
      p.type = parse_type(at, words[1]);
      p.name = std::string(words[2]);
    }
    Element& e = header_.elements.back();
    // Real files have a few dozen; the bound keeps the search for a second one below linear
    // in the header's length.
    if (e.properties.size() >= kMaxPlyProperties)
      at.fail("element " + in_quotes(e.name) + " has more than " +
              std::to_string(kMaxPlyProperties) + " properties");
    if (e.find(p.name)) {
      at.fail("element " + in_quotes(e.name) + " has a second property " + in_quotes(p.name));
    }
    e.properties.push_back(std::move(p));
  }

  Header& header_;
  bool has_format_ = false;
};

}  // namespace

size_t size_of(Type type) { return info(type).bytes; }
bool is_integer(Type type) { return type != Type::kFloat32 && type != Type::kFloat64; }
const char* name_of(Type type) { return info(type).name; }
bool holds(Type type, long long value) {
  return is_integer(type) && value >= info(type).min && value <= info(type).max;
}

std::string number_text(double value) {
  char text[32];
  const bool whole = std::floor(value) == value && std::abs(value) < 1e15;
  std::snprintf(text, sizeof text, whole ? "%.0f" : "%.9g", value);
  return text;
}

std::optional<size_t> Element::find(std::string_view wanted) const {
  for (size_t i = 0; i < properties.size(); ++i) {
    if (properties[i].name == wanted) return i;
  }
  return std::nullopt;
}

Header read_header(std::string_view bytes, const std::string& file) {
  Header header;
  HeaderReader reader(&header);
  size_t start = 0;
  for (size_t number = 1;; ++number) {
    const Where at{file, number};
    const size_t newline = bytes.find('\n', start);
    if (newline == std::string_view::npos && start >= bytes.size()) {
      Where{file, 0}.fail(number == 1 ? "the file is empty; expected a PLY header"
                                      : "the header has no end_header line");
    }
    const size_t end = newline == std::string_view::npos ? bytes.size() : newline;
    std::string_view line = bytes.substr(start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    start = end + 1;
    if (number == 1) {
      // The magic word first, before its bytes are judged as text: a binary file is "not PLY".
      if (line != "ply") at.fail("not a PLY file: the first line must be \"ply\"");
      continue;
    }
    scene_text::check_line_bytes(at, line);
    if (reader.statement(at, scene_text::split_words(line))) {
      header.body_offset = std::min(start, bytes.size());
      header.body_line = number + 1;
      return header;
    }
  }
}

}  // namespace rayfarm::ply
