#pragma once
// The JSON side of the scene format: every value is read through a Node, which knows the file and
// the JSON pointer of the value, so every message can say where the problem is; the readers of
// numbers, vectors, colours and geometry check each value's range as they read it.
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/math/vec3.h"
#include "common/scene/scene_files.h"

namespace rayfarm::scene_json {

using Json = nlohmann::ordered_json;  // keeps materials in file order

/// "string \"x\"", "number 1.5", "an array": what a value is, for "expected ..., got ...".
std::string describe(const Json& value);
/// A string value as written, in quotes ("\"plastic\""); other values as describe() has them.
std::string as_written(const Json& value);
/// `key` escaped for a JSON pointer ("~" and "/").
std::string escape_pointer_token(const std::string& key);

/// The file being read and the warnings found so far.
struct Context {
  std::string file;
  std::vector<std::string>* warnings;
};

/// A JSON value with its place (file and JSON pointer) for messages.
class Node {
 public:
  Node(const Json& value, const Context& context, std::string pointer)
      : value_(&value), context_(&context), pointer_(std::move(pointer)) {}

  const Json& json() const { return *value_; }
  std::string where() const;
  [[noreturn]] void fail(const std::string& what) const { throw SceneError(where() + ": " + what); }
  void warn(const std::string& what) const { context_->warnings->push_back(where() + ": " + what); }

  /// This node as an object; fails otherwise.
  const Json& object() const {
    if (!value_->is_object()) fail("expected an object, got " + describe(*value_));
    return *value_;
  }
  /// This node as an array; fails otherwise.
  const Json& array() const {
    if (!value_->is_array()) fail("expected an array, got " + describe(*value_));
    return *value_;
  }
  Node child(const std::string& key) const {
    return Node(object().at(key), *context_, pointer_ + "/" + escape_pointer_token(key));
  }
  Node child(size_t index) const {
    return Node(array().at(index), *context_, pointer_ + "/" + std::to_string(index));
  }
  std::optional<Node> find(const std::string& key) const {
    if (!object().contains(key)) return std::nullopt;
    return child(key);
  }
  Node require(const std::string& key) const {
    if (!object().contains(key)) fail("missing key \"" + key + "\"");
    return child(key);
  }
  /// Warns about every key of this object that is not in `known`.
  void allow_keys(std::initializer_list<std::string_view> known) const;

 private:
  const Json* value_;
  const Context* context_;
  std::string pointer_;
};

// ---- values ----------------------------------------------------------------------------------

/// A finite number of magnitude at most kMaxAbsNumber.
double read_number(const Node& n);
/// read_number() as a float.
float read_float(const Node& n);
/// A number > 0.
float read_positive(const Node& n);
/// A number >= 0.
float read_non_negative(const Node& n);
/// An integer in [lo, hi].
int64_t read_integer(const Node& n, int64_t lo, int64_t hi);
/// A non-negative integer that fits 64 bits.
uint64_t read_unsigned(const Node& n);
/// true or false.
bool read_bool(const Node& n);
/// A string.
std::string read_string(const Node& n);
/// An array of 3 numbers.
Vec3 read_vec3(const Node& n);
/// A number of geometry (a coordinate or a length): magnitude at most kMaxCoordinate.
float read_coordinate(const Node& n);
/// A point or vector of geometry: 3 numbers of magnitude at most kMaxCoordinate.
Vec3 read_point(const Node& n);
/// A positive length of geometry, at most kMaxCoordinate.
float read_length(const Node& n);
/// An RGB reflectance: every channel in [0, 1].
Vec3 read_reflectance(const Node& n);
/// An RGB radiance or intensity: every channel >= 0.
Vec3 read_radiance(const Node& n);

/// Parses JSON (comments allowed) with at most kMaxJsonNesting levels of arrays and objects;
/// SceneError "FILE: invalid JSON ..." otherwise.
Json parse_json(const std::string& text, const std::string& file);

}  // namespace rayfarm::scene_json
