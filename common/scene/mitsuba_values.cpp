// Typed parameters of Mitsuba 3 plugins: numbers, booleans, strings, points, transforms and
// colours (docs/mitsuba.md, "Values"), each checked where it is written.
#include <charconv>
#include <cmath>

#include "common/limits.h"
#include "common/scene/mitsuba_reader.h"
#include "common/scene/spectra.h"
#include "common/util/text.h"

namespace rayfarm::mitsuba {

void Context::warn_once(const std::string& kind, const XmlElement& at, const std::string& what) {
  if (!warned.insert(kind).second) return;
  scene.warnings.push_back(at.where() + ": " + what);
}

const XmlElement& Context::deref(const XmlElement& e) const {
  if (e.tag != "ref") return e;
  const std::string* id = e.find("id");
  if (id == nullptr) e.fail("<ref> needs an id");
  auto it = ids.find(*id);
  if (it == ids.end()) e.fail("no element has the id \"" + printable(*id) + "\"");
  return *it->second;
}

const std::string& value_of(const XmlElement& e) {
  const std::string* v = e.find("value");
  if (v == nullptr) e.fail("missing the value attribute");
  return *v;
}

std::string type_of(const XmlElement& e) {
  const std::string* t = e.find("type");
  return t == nullptr ? std::string() : *t;
}

namespace {

/// `text` in quotes, made printable and cut at 80 characters, for messages.
std::string quoted(const std::string& text) {
  std::string out(1, '"');
  out += printable(text, 80);
  out += '"';
  return out;
}

}  // namespace

std::vector<double> parse_numbers(const XmlElement& at, const std::string& text) {
  std::vector<double> out;
  const char* p = text.data();
  const char* end = p + text.size();
  while (p < end) {
    if (*p == ',' || *p == ' ' || *p == '\t' || *p == '\n' || *p == '\r') {
      ++p;
      continue;
    }
    double v = 0.0;
    const char* start = p;
    if (*p == '+') ++p;  // from_chars reads no plus sign
    const auto [next, ec] = std::from_chars(p, end, v);
    if (ec != std::errc() || (next < end && !(*next == ',' || *next == ' ' || *next == '\t' ||
                                              *next == '\n' || *next == '\r'))) {
      const std::string here(start, std::min<size_t>(12, static_cast<size_t>(end - start)));
      at.fail(quoted(text) + " is not a list of numbers (at " + quoted(here) + ")");
    }
    // Beyond 1e17 (rayfarm's largest coordinate) a number is no scene's, and as a float it may
    // overflow to infinity on the way.
    if (!(std::fabs(v) <= kMaxCoordinate))
      at.fail(quoted(text) + " holds a number beyond 1e17 (or not finite)");
    out.push_back(v);
    p = next;
  }
  return out;
}

namespace {

double one_number(const XmlElement& e) {
  const std::vector<double> v = parse_numbers(e, value_of(e));
  if (v.size() != 1) e.fail("expected one number, got " + std::to_string(v.size()));
  return v[0];
}

/// x, y, z attributes (each defaulting to `fallback`) or a value attribute of 1 or 3 numbers.
WideVec3 triple(const XmlElement& e, double fallback) {
  if (const std::string* value = e.find("value")) {
    const std::vector<double> v = parse_numbers(e, *value);
    if (v.size() == 1) return {v[0], v[0], v[0]};
    if (v.size() != 3) e.fail("expected 1 or 3 numbers, got " + std::to_string(v.size()));
    return {v[0], v[1], v[2]};
  }
  auto get = [&](const char* key) {
    const std::string* s = e.find(key);
    if (s == nullptr) return fallback;
    const std::vector<double> v = parse_numbers(e, *s);
    if (v.size() != 1) e.fail(std::string("attribute ") + key + ": expected one number");
    return v[0];
  };
  return {get("x"), get("y"), get("z")};
}

WideVec3 named_triple(const XmlElement& e, const char* key) {
  const std::string* s = e.find(key);
  if (s == nullptr) e.fail(std::string("missing the ") + key + " attribute");
  const std::vector<double> v = parse_numbers(e, *s);
  if (v.size() != 3) e.fail(std::string("attribute ") + key + ": expected 3 numbers");
  return {v[0], v[1], v[2]};
}

/// The up of a <lookat> that gives none (or a zero one), as Mitsuba picks it: the first vector
/// of the orthonormal basis it builds around the view direction (Duff et al., "Building an
/// Orthonormal Basis, Revisited", JCGT 2017). Looking along -z, up is +x.
WideVec3 default_up(const WideVec3& dir) {
  const double len = std::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z);
  const WideVec3 n{dir.x / len, dir.y / len, dir.z / len};
  const double sign = std::copysign(1.0, n.z);
  const double a = -1.0 / (sign + n.z), b = n.x * n.y * a;
  return {n.x * n.x * a * sign + 1.0, b * sign, -n.x * sign};
}

Transform operation(const XmlElement& op) {
  if (op.tag == "translate") return Transform::translate(triple(op, 0.0));
  if (op.tag == "scale") {
    const WideVec3 s = triple(op, 1.0);
    return Transform::scale(s);
  }
  if (op.tag == "rotate") {
    const WideVec3 axis = triple(op, 0.0);
    const double len = length(axis);
    if (!(len > 0.0)) op.fail("a rotation needs a non-zero axis (x, y, z or value)");
    const std::string* angle = op.find("angle");
    if (angle == nullptr) op.fail("a rotation needs an angle (degrees)");
    const std::vector<double> a = parse_numbers(op, *angle);
    if (a.size() != 1) op.fail("angle: expected one number");
    return Transform::rotate({axis.x / len, axis.y / len, axis.z / len}, a[0]);
  }
  if (op.tag == "lookat" || op.tag == "look_at") {
    const WideVec3 origin = named_triple(op, "origin"), target = named_triple(op, "target");
    const WideVec3 dir = target - origin;
    if (!(length(dir) > 0.0)) op.fail("origin and target are the same point");
    WideVec3 up{0, 0, 0};
    if (op.find("up") != nullptr) up = named_triple(op, "up");
    if (up.x == 0.0 && up.y == 0.0 && up.z == 0.0) up = default_up(dir);
    if (!(length(cross(up, dir)) > 1e-9 * length(up) * length(dir)))
      op.fail("up is zero or parallel to the view direction");
    return Transform::look_at(origin, target, up);
  }
  if (op.tag == "matrix") {
    const std::vector<double> m = parse_numbers(op, value_of(op));
    if (m.size() == 9)
      return Transform({m[0], m[1], m[2], 0, m[3], m[4], m[5], 0, m[6], m[7], m[8], 0});
    if (m.size() != 16) op.fail("a matrix has 9 or 16 numbers, got " + std::to_string(m.size()));
    if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0)
      op.fail("a projective matrix (last row not 0 0 0 1) is not supported");
    return Transform({m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11]});
  }
  op.fail("unknown transform operation; expected translate, rotate, scale, lookat or matrix");
}

}  // namespace

Props::Props(const XmlElement& e, Context& ctx) : e_(e), ctx_(ctx), read_(e.children.size()) {}

const XmlElement* Props::find(std::string_view name) {
  const XmlElement* found = nullptr;
  for (size_t i = 0; i < e_.children.size(); ++i) {
    const std::string* n = e_.children[i].find("name");
    if (n == nullptr || *n != name) continue;
    if (found != nullptr)
      e_.children[i].fail("the parameter \"" + std::string(name) + "\" is given twice");
    found = &e_.children[i];
    read_[i] = true;
  }
  return found == nullptr ? nullptr : &ctx_.deref(*found);
}

bool Props::has(std::string_view name) const {
  for (const XmlElement& c : e_.children) {
    const std::string* n = c.find("name");
    if (n != nullptr && *n == name) return true;
  }
  return false;
}

double Props::number(std::string_view name, double fallback) {
  const XmlElement* e = find(name);
  if (e == nullptr) return fallback;
  if (e->tag != "float" && e->tag != "integer") e->fail("expected a <float>");
  return one_number(*e);
}

int64_t Props::integer(std::string_view name, int64_t fallback, int64_t lo, int64_t hi) {
  const XmlElement* e = find(name);
  if (e == nullptr) return fallback;
  if (e->tag != "integer") e->fail("expected an <integer>");
  const std::string& v = value_of(*e);
  int64_t out = 0;
  const auto [next, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
  if (ec != std::errc() || next != v.data() + v.size())
    e->fail("\"" + printable(v, 40) + "\" is not an integer");
  if (out < lo || out > hi) {
    e->fail(std::to_string(out) + " lies outside [" + std::to_string(lo) + ", " +
            std::to_string(hi) + "]");
  }
  return out;
}

bool Props::boolean(std::string_view name, bool fallback) {
  const XmlElement* e = find(name);
  if (e == nullptr) return fallback;
  if (e->tag != "boolean") e->fail("expected a <boolean>");
  const std::string& v = value_of(*e);
  if (v == "true" || v == "1") return true;
  if (v == "false" || v == "0") return false;
  e->fail("\"" + printable(v, 40) + "\" is not a boolean (true or false)");
}

std::string Props::string(std::string_view name, const std::string& fallback) {
  const XmlElement* e = find(name);
  if (e == nullptr) return fallback;
  if (e->tag != "string") e->fail("expected a <string>");
  return value_of(*e);
}

std::optional<WideVec3> Props::point(std::string_view name) {
  const XmlElement* e = find(name);
  if (e == nullptr) return std::nullopt;
  if (e->tag != "point" && e->tag != "vector") e->fail("expected a <point> or <vector>");
  return triple(*e, 0.0);
}

Transform Props::transform(std::string_view name) {
  const XmlElement* e = find(name);
  if (e == nullptr) return {};
  if (e->tag != "transform") e->fail("expected a <transform>");
  Transform t;
  for (const XmlElement& op : e->children) t = t.then(operation(op));
  const double det = t.determinant();
  if (!(std::fabs(det) > 0.0) || !std::isfinite(det))
    e->fail("the transform is singular (it flattens shapes)");
  return t;
}

Colour Props::colour(std::string_view name, const Vec3& fallback, SpectrumRole role) {
  const bool bounded = role == SpectrumRole::reflectance;
  const Vec3 white = role == SpectrumRole::emission ? kEmitterWhite : Vec3(1.f);
  const XmlElement* e = find(name);
  Colour c;
  c.value = fallback * white;
  if (e == nullptr) return c;
  if (e->tag == "texture") {
    c.texture = e;
    return c;
  }
  if (e->tag == "rgb") {
    const std::vector<double> v = parse_numbers(*e, value_of(*e));
    if (v.size() == 1)
      c.value = Vec3(float(v[0]));
    else if (v.size() == 3)
      c.value = Vec3(float(v[0]), float(v[1]), float(v[2]));
    else
      e->fail("an RGB has 1 or 3 numbers, got " + std::to_string(v.size()));
  } else if (e->tag == "float" || e->tag == "integer") {
    c.value = float(one_number(*e)) * white;
  } else if (e->tag == "spectrum") {
    if (e->find("filename") != nullptr)
      e->fail("spectra from files are not supported; give wavelength:value pairs");
    const std::string& text = value_of(*e);
    if (text.find(':') == std::string::npos) {
      const std::vector<double> v = parse_numbers(*e, text);
      if (v.size() != 1) e->fail("a spectrum is one number or wavelength:value pairs");
      c.value = float(v[0]) * white;  // in RGB, a uniform spectrum is grey (emitters: white)
    } else {
      std::vector<double> wavelengths, values;
      std::string cleaned = text;
      for (char& ch : cleaned) {
        if (ch == ':') ch = ' ';
      }
      const std::vector<double> pairs = parse_numbers(*e, cleaned);
      if (pairs.size() % 2 != 0) e->fail("wavelength:value pairs expected");
      for (size_t i = 0; i < pairs.size(); i += 2) {
        wavelengths.push_back(pairs[i]);
        values.push_back(pairs[i + 1]);
      }
      try {
        c.value = spectrum_to_rgb(wavelengths, values, role);
      } catch (const std::invalid_argument& err) {
        e->fail(err.what());
      }
    }
  } else {
    e->fail("expected an <rgb>, <spectrum>, <float> or <texture>");
  }
  if (!is_finite(c.value)) e->fail("the colour is not finite");
  if (bounded && !(min_component(c.value) >= 0.f && max_component(c.value) <= 1.f))
    e->fail("a reflectance must lie in [0, 1] in every channel");
  if (!bounded && !(min_component(c.value) >= 0.f)) e->fail("the value must not be negative");
  return c;
}

Colour Props::scalar(std::string_view name, float fallback) {
  const XmlElement* e = find(name);
  Colour c;
  c.value = Vec3(fallback);
  if (e == nullptr) return c;
  if (e->tag == "texture") {
    c.texture = e;
    return c;
  }
  if (e->tag != "float" && e->tag != "integer") e->fail("expected a <float> or a <texture>");
  c.value = Vec3(float(one_number(*e)));
  return c;
}

std::vector<const XmlElement*> Props::plugins(std::string_view tag) {
  std::vector<const XmlElement*> out;
  for (size_t i = 0; i < e_.children.size(); ++i) {
    if (read_[i]) continue;  // a named parameter already taken
    const XmlElement& target = ctx_.deref(e_.children[i]);
    if (target.tag != tag) continue;
    read_[i] = true;
    out.push_back(&target);
  }
  return out;
}

void Props::finish(std::initializer_list<std::string_view> ignored) {
  for (size_t i = 0; i < e_.children.size(); ++i) {
    if (read_[i]) continue;
    const XmlElement& c = e_.children[i];
    const std::string* name = c.find("name");
    const std::string label =
        name != nullptr ? "\"" + printable(*name, 64) + "\"" : "<" + printable(c.tag, 32) + ">";
    bool harmless = false;
    for (std::string_view k : ignored) harmless = harmless || (name != nullptr && *name == k);
    if (harmless) {
      ctx_.warn_once(e_.tag + type_of(e_) + *name, c,
                     "ignored: the parameter " + label + " changes nothing rayfarm renders");
      continue;
    }
    c.fail("the parameter " + label + " of " + e_.tag + " \"" + printable(type_of(e_), 32) +
           "\" is not supported (docs/mitsuba.md lists what is)");
  }
}

}  // namespace rayfarm::mitsuba
