#include "common/scene/json_reader.h"

#include <cmath>

#include "common/limits.h"
#include "common/util/text.h"

namespace rayfarm::scene_json {
namespace {

constexpr size_t kMaxStringInMessage = 40;

/// Thrown by the parse callback when the nesting limit is reached.
struct NestingTooDeep {};

}  // namespace

std::string describe(const Json& value) {
  switch (value.type()) {
    case Json::value_t::null:
      return "null";
    case Json::value_t::boolean:
      return value.get<bool>() ? "true" : "false";
    case Json::value_t::object:
      return "an object";
    case Json::value_t::array:
      return "an array";
    case Json::value_t::string: {
      const auto& s = value.get_ref<const std::string&>();
      if (s.size() <= kMaxStringInMessage) return "string " + printable(Json(s).dump());
      return "string " + printable(Json(s.substr(0, kMaxStringInMessage)).dump()) + "...";
    }
    default:
      return "number " + value.dump();
  }
}

std::string as_written(const Json& value) {
  return value.is_string() ? describe(value).substr(std::string("string ").size())
                           : describe(value);
}

std::string escape_pointer_token(const std::string& key) {
  std::string out;
  for (char c : key) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}

std::string Node::where() const {
  return context_->file + ": " +
         (pointer_.empty() ? std::string("(top level)") : printable(pointer_));
}

void Node::allow_keys(std::initializer_list<std::string_view> known) const {
  for (const auto& [key, value] : object().items()) {
    bool found = false;
    for (std::string_view k : known) found = found || k == key;
    if (!found) child(key).warn("unknown key \"" + printable(key) + "\" ignored");
  }
}

double read_number(const Node& n) {
  const Json& v = n.json();
  if (!v.is_number()) n.fail("expected a number, got " + describe(v));
  const double x = v.get<double>();
  if (!std::isfinite(x) || std::abs(x) > kMaxAbsNumber) {
    n.fail("number " + v.dump() + " is out of range (magnitude at most 1e30)");
  }
  return x;
}

float read_float(const Node& n) { return static_cast<float>(read_number(n)); }

float read_positive(const Node& n) {
  const float x = read_float(n);
  if (!(x > 0.f)) n.fail("must be positive, got " + n.json().dump());
  return x;
}

float read_non_negative(const Node& n) {
  const float x = read_float(n);
  if (x < 0.f) n.fail("must not be negative, got " + n.json().dump());
  return x;
}

int64_t read_integer(const Node& n, int64_t lo, int64_t hi) {
  const Json& v = n.json();
  if (!v.is_number_integer()) n.fail("expected an integer, got " + describe(v));
  // Non-negative literals parse as unsigned, which may exceed int64_t.
  const bool fits = !v.is_number_unsigned() || v.get<uint64_t>() <= static_cast<uint64_t>(hi);
  const bool in_range = fits && v.get<int64_t>() >= lo && v.get<int64_t>() <= hi;
  if (!in_range) {
    n.fail("must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi) +
           ", got " + v.dump());
  }
  return v.get<int64_t>();
}

uint64_t read_unsigned(const Node& n) {
  const Json& v = n.json();
  if (!v.is_number_integer() || (!v.is_number_unsigned() && v.get<int64_t>() < 0)) {
    n.fail("expected an unsigned integer, got " + describe(v));
  }
  return v.get<uint64_t>();
}

bool read_bool(const Node& n) {
  if (!n.json().is_boolean()) n.fail("expected true or false, got " + describe(n.json()));
  return n.json().get<bool>();
}

std::string read_string(const Node& n) {
  if (!n.json().is_string()) n.fail("expected a string, got " + describe(n.json()));
  return n.json().get<std::string>();
}

Vec3 read_vec3(const Node& n) {
  const Json& v = n.array();
  if (v.size() != 3)
    n.fail("expected an array of 3 numbers, got " + std::to_string(v.size()) + " values");
  return {read_float(n.child(0)), read_float(n.child(1)), read_float(n.child(2))};
}

/// A number of geometry (a coordinate or a length): magnitude at most kMaxCoordinate.
float read_coordinate(const Node& n) {
  const float x = read_float(n);
  if (std::abs(double(x)) > kMaxCoordinate) {
    n.fail("coordinate " + n.json().dump() +
           " is beyond 1e17, the largest that the renderer handles (rays are traced within "
           "+-1.8e18)");
  }
  return x;
}

/// A point or vector of geometry: 3 numbers of magnitude at most kMaxCoordinate.
Vec3 read_point(const Node& n) {
  (void)read_vec3(n);
  return {read_coordinate(n.child(0)), read_coordinate(n.child(1)), read_coordinate(n.child(2))};
}

/// A positive length of geometry, at most kMaxCoordinate.
float read_length(const Node& n) {
  (void)read_positive(n);
  return read_coordinate(n);
}

/// An RGB reflectance: every channel in [0, 1].
Vec3 read_reflectance(const Node& n) {
  const Vec3 c = read_vec3(n);
  for (size_t i = 0; i < 3; ++i) {
    if (c[int(i)] < 0.f || c[int(i)] > 1.f) {
      n.child(i).fail("a reflectance must lie in [0, 1], got " + n.child(i).json().dump());
    }
  }
  return c;
}

/// An RGB radiance or intensity: every channel >= 0.
Vec3 read_radiance(const Node& n) {
  const Vec3 c = read_vec3(n);
  for (size_t i = 0; i < 3; ++i) read_non_negative(n.child(i));
  return c;
}

Json parse_json(const std::string& text, const std::string& file) {
  const Json::parser_callback_t limit = [](int depth, Json::parse_event_t event, Json&) {
    const bool opens =
        event == Json::parse_event_t::object_start || event == Json::parse_event_t::array_start;
    if (opens && depth >= kMaxJsonNesting) throw NestingTooDeep{};
    return true;
  };
  try {
    return Json::parse(text, limit, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const NestingTooDeep&) {
    throw SceneError(file + ": invalid JSON: arrays and objects nested more than " +
                     std::to_string(kMaxJsonNesting) + " levels deep");
  } catch (const Json::parse_error& e) {
    const std::string what = e.what();
    throw SceneError(file + ": invalid JSON (byte " + std::to_string(e.byte) +
                     "): " + printable(what.substr(what.find(']') + 2)));
  } catch (const Json::exception& e) {
    const std::string what = e.what();
    throw SceneError(file + ": invalid JSON: " + printable(what.substr(what.find(']') + 2)));
  }
}

}  // namespace rayfarm::scene_json
