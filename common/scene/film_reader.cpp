#include "common/scene/film_reader.h"

#include <string>

#include <fmt/format.h>

namespace rayfarm {

using scene_json::Node;

namespace {

/// A number within [lo, hi].
float read_within(const Node& n, float lo, float hi, const char* what) {
  const float v = scene_json::read_float(n);
  if (!(v >= lo && v <= hi))
    n.fail(fmt::format("{} must lie in [{}, {}], got {}", what, lo, hi, v));
  return v;
}

}  // namespace

PixelFilter read_pixel_filter(const std::optional<Node>& filter,
                              const std::optional<Node>& sample_border) {
  PixelFilter f;
  if (sample_border) f.sample_border = scene_json::read_bool(*sample_border);
  if (!filter) return f;
  const bool object = filter->json().is_object();
  const Node type_node = object ? filter->require("type") : *filter;
  const std::string type = scene_json::read_string(type_node);
  const auto param = [&](const char* key) { return object ? filter->find(key) : std::nullopt; };
  if (type == "box" || type == "tent") {
    f.type = type == "box" ? FilterType::kBox : FilterType::kTent;
    if (object) filter->allow_keys({"type", "radius"});
    f.radius = type == "box" ? 0.5f : 1.f;
    if (auto r = param("radius"))
      f.radius = read_within(*r, kMinFilterRadius, kMaxFilterRadius, "radius");
  } else if (type == "gaussian") {
    f.type = FilterType::kGaussian;
    if (object) filter->allow_keys({"type", "stddev"});
    if (auto s = param("stddev"))
      f.stddev = read_within(*s, kMinFilterRadius / 4.f, kMaxFilterRadius / 4.f, "stddev");
    f.radius = 4.f * f.stddev;
  } else if (type == "mitchell" || type == "catmull-rom") {
    f.type = FilterType::kMitchell;
    f.radius = 2.f;
    if (type == "catmull-rom") {
      if (object) filter->allow_keys({"type"});
      f.b = 0.f;
      f.c = 0.5f;
    } else {
      if (object) filter->allow_keys({"type", "b", "c"});
      if (auto b = param("b")) f.b = read_within(*b, 0.f, 1.f, "b");
      if (auto c = param("c")) f.c = read_within(*c, 0.f, 1.f, "c");
    }
  } else if (type == "lanczos") {
    f.type = FilterType::kLanczos;
    if (object) filter->allow_keys({"type", "lobes"});
    f.radius = 3.f;
    if (auto l = param("lobes"))
      f.radius = static_cast<float>(scene_json::read_integer(*l, 1, int64_t(kMaxFilterRadius)));
  } else if (type == "blackman-harris") {
    f.type = FilterType::kBlackmanHarris;
    if (object) filter->allow_keys({"type", "width"});
    f.radius = 0.75f;  // width 1.5 pixels, Cycles' default
    if (auto w = param("width"))
      f.radius = 0.5f * read_within(*w, 2.f * kMinFilterRadius, 2.f * kMaxFilterRadius, "width");
  } else {
    type_node.fail("unknown filter " + scene_json::as_written(type_node.json()) +
                   " (box, tent, gaussian, mitchell, catmull-rom, lanczos or blackman-harris)");
  }
  return f;
}

}  // namespace rayfarm
