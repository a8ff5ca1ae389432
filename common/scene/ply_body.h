#pragma once
// The body of a PLY file, read one value at a time in the order the header declares them: an
// ASCII body (one line per record) or a binary one (either byte order). Both readers have the same
// members, so that the mesh reader (ply_loader.cpp) is written once over either; both name the
// place of every problem: the element, the record's number and its line or byte offset.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/scene/ply_header.h"

namespace rayfarm::ply {

/// An ASCII body: each record of an element with properties is one line, its values separated by
/// blanks; blank lines are skipped.
class AsciiBody {
 public:
  AsciiBody(std::string_view bytes, const Header& header, std::string file);

  /// Before anything is allocated: the records of the elements with properties (those with
  /// `min_bytes` above 0) need a line each.
  void check_counts(const std::vector<Element>& elements,
                    const std::vector<uint64_t>& min_bytes) const;
  /// Starts record `index` of `element`: its line.
  void begin(const Element& element, uint64_t index);
  /// The value of a scalar property (an integer type's within its range; a float's finite and at
  /// most 1e30 in magnitude).
  double value(const Property& p);
  /// The length of a list property; its items must be on the line.
  uint64_t length(const Property& p);
  /// One item of a list property.
  double item(const Property& p);
  void skip_value(const Property& p);
  void skip_items(const Property& p, uint64_t count);
  /// Ends the record: its line must hold nothing more.
  void end();
  /// After the last element: lines left over are ignored with a warning.
  void finish(std::vector<std::string>* warnings);

  /// "FILE:LINE: vertex 3", the record being read.
  std::string place() const;
  [[noreturn]] void fail(const std::string& what) const;

 private:
  double number(const Property& p, Type type);
  std::string_view word(const Property& p);
  /// The next non-blank line from `pos`, or false at the end (`pos` and `line` move past it).
  bool next_line(size_t* pos, size_t* line, std::string_view* text) const;

  std::string_view bytes_;
  std::string file_;
  size_t pos_ = 0;
  size_t line_ = 0;  ///< the number of the line last read
  const Element* element_ = nullptr;
  uint64_t index_ = 0;
  std::vector<std::string_view> words_;
  size_t next_ = 0;  ///< the next word of words_ to read
};

/// A binary body: the values packed, in the header's byte order.
class BinaryBody {
 public:
  BinaryBody(std::string_view bytes, const Header& header, std::string file);

  /// Before anything is allocated: `min_bytes[i]` bytes per record of element i must fit in the
  /// bytes after the header, all elements together.
  void check_counts(const std::vector<Element>& elements,
                    const std::vector<uint64_t>& min_bytes) const;
  void begin(const Element& element, uint64_t index);
  double value(const Property& p) { return read(p, p.type); }
  /// The length of a list property; its items must fit in the bytes left.
  uint64_t length(const Property& p);
  double item(const Property& p) { return read(p, p.type); }
  void skip_value(const Property& p);
  void skip_items(const Property& p, uint64_t count);
  void end() {}
  /// After the last element: bytes left over are ignored with a warning.
  void finish(std::vector<std::string>* warnings);

  /// "FILE: vertex 3 (byte 1234)", the record being read and where it starts.
  std::string place() const;
  [[noreturn]] void fail(const std::string& what) const;

 private:
  double read(const Property& p, Type type);

  std::string_view bytes_;
  std::string file_;
  size_t start_ = 0;  ///< the body's first byte
  size_t pos_ = 0;
  bool swap_ = false;  ///< the file's byte order is not this machine's
  const Element* element_ = nullptr;
  uint64_t index_ = 0;
  size_t record_ = 0;  ///< where the record being read starts
};

}  // namespace rayfarm::ply
