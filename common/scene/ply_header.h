#pragma once
// The header of a Stanford PLY file: its format and the elements and properties it declares, read
// and checked line by line so that every problem is reported as FILE:LINE (docs/scene-format.md,
// "PLY meshes"). What the elements mean is the mesh reader's business (ply_loader.h).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rayfarm::ply {

enum class Format { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

/// The scalar types of PLY, each under its two names (char and int8, ..., double and float64).
enum class Type : uint8_t { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

/// Bytes of one value of `type` in a binary body.
size_t size_of(Type type);
bool is_integer(Type type);
/// The name of `type` as written in headers ("uchar", "float", ...).
const char* name_of(Type type);
/// Whether the integer `value` is representable in the integer `type`.
bool holds(Type type, long long value);

/// A value read from a file, for a message: whole numbers in full, others to 9 digits.
std::string number_text(double value);

struct Property {
  std::string name;
  Type type = Type::kFloat32;  ///< the value's type; for a list, its items' type
  bool is_list = false;
  Type count_type = Type::kUint8;  ///< a list's length type (an integer type)
  size_t line = 0;                 ///< the header line that declares it
};

struct Element {
  std::string name;
  uint64_t count = 0;
  size_t line = 0;  ///< the header line that declares it
  std::vector<Property> properties;

  /// The index of the property `name`, if the element has one.
  std::optional<size_t> find(std::string_view name) const;
};

struct Header {
  Format format = Format::kAscii;
  std::vector<Element> elements;
  size_t body_offset = 0;  ///< the first byte after the end_header line
  size_t body_line = 0;    ///< the number of the body's first line (for an ASCII body)
};

/// Reads the header at the start of `bytes`. Throws SceneError "FILE:LINE: ..." when it is not a
/// PLY header, lacks its format or end_header line, or declares something malformed.
Header read_header(std::string_view bytes, const std::string& file);

}  // namespace rayfarm::ply
