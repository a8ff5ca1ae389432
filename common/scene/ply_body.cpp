// PLY bodies. Nothing here trusts the header's counts: every length is checked against the bytes
// (or the words of the line) actually left before it is used, so that a lying header ends in an
// error that names the record, never in a read past the end or a giant allocation.
#include "common/scene/ply_body.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <system_error>

#include "common/scene/text_lines.h"

namespace rayfarm::ply {
using scene_text::in_quotes;

namespace {

std::string records(uint64_t count) {
  return std::to_string(count) + (count == 1 ? " record" : " records");
}

[[noreturn]] void fail_at_element(const std::string& file, const Element& e,
                                  const std::string& what) {
  throw SceneError(file + ":" + std::to_string(e.line) + ": element " + in_quotes(e.name) + ": " +
                   what);
}

template <class T>
T load(const char* p, bool swap) {
  unsigned char raw[sizeof(T)];
  std::memcpy(raw, p, sizeof(T));
  if (swap) std::reverse(raw, raw + sizeof(T));
  T value;
  std::memcpy(&value, raw, sizeof(T));
  return value;
}

}  // namespace

// ---- ASCII ------------------------------------------------------------------------------------

AsciiBody::AsciiBody(std::string_view bytes, const Header& header, std::string file)
    : bytes_(bytes),
      file_(std::move(file)),
      pos_(header.body_offset),
      line_(header.body_line - 1) {}

bool AsciiBody::next_line(size_t* pos, size_t* line, std::string_view* text) const {
  while (*pos < bytes_.size()) {
    size_t end = bytes_.find('\n', *pos);
    if (end == std::string_view::npos) end = bytes_.size();
    std::string_view found = bytes_.substr(*pos, end - *pos);
    *pos = end + 1;
    ++*line;
    if (!found.empty() && found.back() == '\r') found.remove_suffix(1);
    if (found.find_first_not_of(" \t") != std::string_view::npos) {
      *text = found;
      return true;
    }
  }
  return false;
}

void AsciiBody::check_counts(const std::vector<Element>& elements,
                             const std::vector<uint64_t>& min_bytes) const {
  uint64_t lines = 0;
  size_t pos = pos_, line = line_;
  std::string_view text;
  while (next_line(&pos, &line, &text)) ++lines;
  uint64_t used = 0;
  for (size_t i = 0; i < elements.size(); ++i) {
    const Element& e = elements[i];
    if (min_bytes[i] == 0) continue;  // its records have no values, hence no lines
    if (e.count > lines - used) {
      fail_at_element(file_, e,
                      "the header declares " + records(e.count) + ", one line each, but only " +
                          std::to_string(lines - used) + " of the body's " + std::to_string(lines) +
                          " non-blank lines are left for them");
    }
    used += e.count;
  }
}

void AsciiBody::begin(const Element& element, uint64_t index) {
  element_ = &element;
  index_ = index;
  std::string_view text;
  if (!next_line(&pos_, &line_, &text)) fail("the file ends before this record");
  scene_text::check_line_bytes({file_, line_}, text);
  words_ = scene_text::split_words(text);
  next_ = 0;
}

std::string_view AsciiBody::word(const Property& p) {
  if (next_ >= words_.size()) {
    fail("the line ends after " + std::to_string(words_.size()) + " values; property " +
         in_quotes(p.name) + " needs more");
  }
  return words_[next_++];
}

double AsciiBody::number(const Property& p, Type type) {
  const std::string_view w = word(p);
  if (is_integer(type)) {
    std::string_view digits = w;
    if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
    long long value = 0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (error != std::errc() || end != digits.data() + digits.size() || !holds(type, value)) {
      fail("property " + in_quotes(p.name) + ": " + in_quotes(w) + " is not a value of type " +
           name_of(type));
    }
    return static_cast<double>(value);
  }
  const auto value = scene_text::parse_number(w);
  if (!value) {
    fail("property " + in_quotes(p.name) + ": " + in_quotes(w) +
         " is not a finite number of magnitude at most 1e30");
  }
  return *value;
}

double AsciiBody::value(const Property& p) { return number(p, p.type); }
double AsciiBody::item(const Property& p) { return number(p, p.type); }

uint64_t AsciiBody::length(const Property& p) {
  const double n = number(p, p.count_type);
  if (n < 0) fail("list " + in_quotes(p.name) + " has a negative length, " + number_text(n));
  const size_t left = words_.size() - next_;
  if (n > static_cast<double>(left)) {
    fail("list " + in_quotes(p.name) + " has " + number_text(n) + " items, but the line has only " +
         std::to_string(left) + " values left");
  }
  return static_cast<uint64_t>(n);
}

void AsciiBody::skip_value(const Property& p) { word(p); }

void AsciiBody::skip_items(const Property& p, uint64_t count) {
  (void)p;  // length() checked that the items are on the line
  next_ += static_cast<size_t>(count);
}

void AsciiBody::end() {
  if (next_ < words_.size()) {
    fail("the line has " + std::to_string(words_.size()) + " values, " +
         std::to_string(words_.size() - next_) + " more than the element's properties take");
  }
}

void AsciiBody::finish(std::vector<std::string>* warnings) {
  size_t pos = pos_, line = line_;
  std::string_view text;
  uint64_t extra = 0;
  size_t first = 0;
  while (next_line(&pos, &line, &text)) {
    if (extra++ == 0) first = line;
  }
  if (extra > 0) {
    warnings->push_back(file_ + ":" + std::to_string(first) + ": " + std::to_string(extra) +
                        " line(s) after the last element are ignored");
  }
}

std::string AsciiBody::place() const {
  return file_ + ":" + std::to_string(line_) + ": " + element_->name + " " + std::to_string(index_);
}

void AsciiBody::fail(const std::string& what) const { throw SceneError(place() + ": " + what); }

// ---- binary -----------------------------------------------------------------------------------

BinaryBody::BinaryBody(std::string_view bytes, const Header& header, std::string file)
    : bytes_(bytes),
      file_(std::move(file)),
      start_(header.body_offset),
      pos_(header.body_offset),
      swap_((header.format == Format::kBinaryBigEndian) !=
            (std::endian::native == std::endian::big)) {}

void BinaryBody::check_counts(const std::vector<Element>& elements,
                              const std::vector<uint64_t>& min_bytes) const {
  const uint64_t body = bytes_.size() - start_;
  uint64_t used = 0;
  for (size_t i = 0; i < elements.size(); ++i) {
    const Element& e = elements[i];
    if (min_bytes[i] == 0) continue;
    const uint64_t left = body - used;
    if (e.count > left / min_bytes[i]) {
      fail_at_element(file_, e,
                      "the header declares " + records(e.count) + " of at least " +
                          std::to_string(min_bytes[i]) + " bytes each, but only " +
                          std::to_string(left) + " bytes are left for them (from byte " +
                          std::to_string(start_ + used) + "; the file has " +
                          std::to_string(bytes_.size()) + ")");
    }
    used += e.count * min_bytes[i];
  }
}

void BinaryBody::begin(const Element& element, uint64_t index) {
  element_ = &element;
  index_ = index;
  record_ = pos_;
}

double BinaryBody::read(const Property& p, Type type) {
  const size_t size = size_of(type);
  if (bytes_.size() - pos_ < size) {
    fail("the file ends at byte " + std::to_string(bytes_.size()) + ", inside property " +
         in_quotes(p.name));
  }
  const char* at = bytes_.data() + pos_;
  pos_ += size;
  switch (type) {
    case Type::kInt8:
      return load<int8_t>(at, swap_);
    case Type::kUint8:
      return load<uint8_t>(at, swap_);
    case Type::kInt16:
      return load<int16_t>(at, swap_);
    case Type::kUint16:
      return load<uint16_t>(at, swap_);
    case Type::kInt32:
      return load<int32_t>(at, swap_);
    case Type::kUint32:
      return load<uint32_t>(at, swap_);
    case Type::kFloat32:
      return load<float>(at, swap_);
    case Type::kFloat64:
      return load<double>(at, swap_);
  }
  return 0.0;
}

uint64_t BinaryBody::length(const Property& p) {
  const double n = read(p, p.count_type);
  if (n < 0) fail("list " + in_quotes(p.name) + " has a negative length, " + number_text(n));
  const size_t item = size_of(p.type);
  const size_t left = bytes_.size() - pos_;
  if (n > static_cast<double>(left / item)) {
    fail("list " + in_quotes(p.name) + " has " + number_text(n) + " items of " +
         std::to_string(item) + " bytes, but only " + std::to_string(left) +
         " bytes are left in the file");
  }
  return static_cast<uint64_t>(n);
}

void BinaryBody::skip_value(const Property& p) {
  const size_t size = size_of(p.type);
  if (bytes_.size() - pos_ < size) {
    fail("the file ends at byte " + std::to_string(bytes_.size()) + ", inside property " +
         in_quotes(p.name));
  }
  pos_ += size;
}

void BinaryBody::skip_items(const Property& p, uint64_t count) {
  pos_ += static_cast<size_t>(count) * size_of(p.type);  // length() checked that they fit
}

void BinaryBody::finish(std::vector<std::string>* warnings) {
  if (pos_ < bytes_.size()) {
    warnings->push_back(file_ + ": " + std::to_string(bytes_.size() - pos_) +
                        " byte(s) after the last element (from byte " + std::to_string(pos_) +
                        ") are ignored");
  }
}

std::string BinaryBody::place() const {
  return file_ + ": " + element_->name + " " + std::to_string(index_) + " (byte " +
         std::to_string(record_) + ")";
}

void BinaryBody::fail(const std::string& what) const { throw SceneError(place() + ": " + what); }

}  // namespace rayfarm::ply
