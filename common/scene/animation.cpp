#include "common/scene/animation.h"

#include <algorithm>
#include <cmath>
#include <string_view>
#include <vector>

#include "common/scene/scene_files.h"

namespace rayfarm {
namespace scene_json {
namespace {

/// Top-level sections whose values are the same for every frame.
constexpr std::string_view kStillSections[] = {"film", "render", "format", "gltf", "animation"};

/// The most numbers one keyframed value may have (a 4x4 matrix).
constexpr size_t kMaxKeyframeComponents = 16;

enum class Interpolation { kLinear, kSmooth, kStep };

bool is_keyframed(const Json& v) { return v.is_object() && v.contains("keyframes"); }

bool has_keyframes(const Json& v) {
  if (is_keyframed(v)) return true;
  if (v.is_object() || v.is_array()) {
    for (const Json& child : v) {
      if (has_keyframes(child)) return true;
    }
  }
  return false;
}

/// The keys of one keyframed value: their frames, and their numbers key by key.
struct Track {
  std::vector<double> frames;
  std::vector<std::vector<double>> values;  // values[key][component]
  bool scalar = true;                       // numbers, not arrays
  Interpolation interpolation = Interpolation::kLinear;
};

Track read_track(const Node& n) {
  n.allow_keys({"keyframes", "interpolation"});
  Track track;
  if (auto i = n.find("interpolation")) {
    const std::string name = read_string(*i);
    if (name == "linear") {
      track.interpolation = Interpolation::kLinear;
    } else if (name == "smooth") {
      track.interpolation = Interpolation::kSmooth;
    } else if (name == "step") {
      track.interpolation = Interpolation::kStep;
    } else {
      i->fail("unknown interpolation " + as_written(i->json()) +
              " (expected \"linear\", \"smooth\" or \"step\")");
    }
  }
  const Node keys = n.require("keyframes");
  if (keys.array().empty()) keys.fail("expected at least one keyframe, got none");
  for (size_t k = 0; k < keys.array().size(); ++k) {
    const Node key = keys.child(k);
    if (key.array().size() != 2) {
      key.fail("expected a keyframe [FRAME, VALUE], got an array of " +
               std::to_string(key.array().size()) + " values");
    }
    const Node frame = key.child(size_t{0});
    const Node value = key.child(size_t{1});
    const double f = read_number(frame);
    if (std::abs(f) > double(kMaxFrameNumber)) {
      frame.fail("frame " + frame.json().dump() + " is out of range (magnitude at most 1e9)");
    }
    if (!track.frames.empty() && !(f > track.frames.back())) {
      frame.fail("keyframes must be in increasing frame order: frame " + frame.json().dump() +
                 " comes after frame " + Json(track.frames.back()).dump());
    }
    std::vector<double> numbers;
    const bool scalar = !value.json().is_array();
    if (scalar) {
      numbers.push_back(read_number(value));
    } else {
      const size_t size = value.array().size();
      if (size == 0 || size > kMaxKeyframeComponents) {
        value.fail("expected a number or an array of 1 to 16 numbers, got an array of " +
                   std::to_string(size));
      }
      for (size_t c = 0; c < size; ++c) numbers.push_back(read_number(value.child(c)));
    }
    if (k > 0 && (scalar != track.scalar || numbers.size() != track.values[0].size())) {
      value.fail("every keyframe's value must have the shape of the first (" +
                 (track.scalar ? std::string("a number")
                               : "an array of " + std::to_string(track.values[0].size())) +
                 ")");
    }
    track.scalar = scalar;
    track.frames.push_back(f);
    track.values.push_back(std::move(numbers));
  }
  return track;
}

/// The tangent of a smooth track at key k, component c: zero at the first and last key and
/// where the values turn (a local extreme), else the mean of the neighbouring slopes limited to
/// three times the smaller one, which keeps the curve between the values of each segment
/// (monotone cubic interpolation, Fritsch and Carlson 1980): a smooth value never overshoots its
/// keys, so an intensity keyed at zero never goes negative.
double smooth_tangent(const Track& t, size_t k, size_t c) {
  if (k == 0 || k + 1 == t.frames.size()) return 0.0;
  const double before = (t.values[k][c] - t.values[k - 1][c]) / (t.frames[k] - t.frames[k - 1]);
  const double after = (t.values[k + 1][c] - t.values[k][c]) / (t.frames[k + 1] - t.frames[k]);
  if (before * after <= 0.0) return 0.0;
  const double mean = 0.5 * (before + after);
  const double limit = 3.0 * std::min(std::abs(before), std::abs(after));
  return std::copysign(std::min(std::abs(mean), limit), mean);
}

Json evaluate(const Track& t, double frame) {
  std::vector<double> out;
  if (frame <= t.frames.front()) {
    out = t.values.front();
  } else if (frame >= t.frames.back()) {
    out = t.values.back();
  } else {
    // The segment [k, k + 1] holding the frame.
    const size_t k =
        size_t(std::upper_bound(t.frames.begin(), t.frames.end(), frame) - t.frames.begin()) - 1;
    const double h = t.frames[k + 1] - t.frames[k];
    const double s = (frame - t.frames[k]) / h;
    out.resize(t.values[k].size());
    for (size_t c = 0; c < out.size(); ++c) {
      const double a = t.values[k][c], b = t.values[k + 1][c];
      switch (t.interpolation) {
        case Interpolation::kStep:
          out[c] = a;
          break;
        case Interpolation::kLinear:
          out[c] = a + (b - a) * s;
          break;
        case Interpolation::kSmooth: {
          // Cubic Hermite on the segment.
          const double s2 = s * s, s3 = s2 * s;
          const double ma = smooth_tangent(t, k, c) * h, mb = smooth_tangent(t, k + 1, c) * h;
          out[c] = (2 * s3 - 3 * s2 + 1) * a + (s3 - 2 * s2 + s) * ma + (-2 * s3 + 3 * s2) * b +
                   (s3 - s2) * mb;
          break;
        }
      }
      // Within the keys' range (a monotone curve cannot leave it; this guards rounding).
      out[c] = std::clamp(out[c], std::min(a, b), std::max(a, b));
    }
  }
  if (t.scalar) return Json(out[0]);
  Json array = Json::array();
  for (double v : out) array.push_back(v);
  return array;
}

Json resolve(const Node& n, double frame, const std::string* refusal) {
  const Json& v = n.json();
  if (is_keyframed(v)) {
    if (refusal) n.fail(*refusal);
    return evaluate(read_track(n), frame);
  }
  if (v.is_object()) {
    Json out = Json::object();
    for (const auto& [key, child] : v.items()) out[key] = resolve(n.child(key), frame, refusal);
    return out;
  }
  if (v.is_array()) {
    Json out = Json::array();
    for (size_t i = 0; i < v.size(); ++i) out.push_back(resolve(n.child(i), frame, refusal));
    return out;
  }
  return v;
}

int64_t read_frame_number(const Node& n) {
  return read_integer(n, -kMaxFrameNumber, kMaxFrameNumber);
}

}  // namespace

std::optional<FrameRange> read_animation(const Node& root) {
  const auto a = root.find("animation");
  if (!a) return std::nullopt;
  a->allow_keys({"frames", "fps"});
  FrameRange range;
  const Node frames = a->require("frames");
  if (frames.array().size() != 2) {
    frames.fail("expected [FIRST, LAST], got an array of " + std::to_string(frames.array().size()) +
                " values");
  }
  range.first = read_frame_number(frames.child(size_t{0}));
  range.last = read_frame_number(frames.child(size_t{1}));
  if (range.last < range.first) {
    frames.fail("the last frame (" + std::to_string(range.last) + ") comes before the first (" +
                std::to_string(range.first) + ")");
  }
  if (auto fps = a->find("fps")) {
    range.fps = read_positive(*fps);
    if (range.fps > 1000.0) fps->fail("at most 1000 frames a second");
  }
  return range;
}

std::optional<Json> resolve_keyframes(const Node& root, const std::optional<FrameRange>& animation,
                                      double frame) {
  if (!has_keyframes(root.json())) return std::nullopt;
  const std::string still =
      "a keyframed value needs an \"animation\" block at the top level, giving the frames";
  Json out = Json::object();
  for (const auto& [key, child] : root.object().items()) {
    std::string section_refusal;
    if (animation && std::find(std::begin(kStillSections), std::end(kStillSections), key) !=
                         std::end(kStillSections)) {
      section_refusal = "\"" + key +
                        "\" cannot be keyframed: every frame of a sequence has the same film, "
                        "render settings and files";
    }
    const std::string* refusal =
        !animation ? &still : (section_refusal.empty() ? nullptr : &section_refusal);
    out[key] = resolve(root.child(key), frame, refusal);
  }
  return out;
}

}  // namespace scene_json

void check_frame(const std::string& file, const std::optional<FrameRange>& animation,
                 std::optional<int64_t> frame) {
  if (!frame) return;
  if (!animation) {
    throw SceneError(file + ": frame " + std::to_string(*frame) +
                     " was asked for, but the scene is a still (it has no animation)");
  }
  if (!animation->contains(*frame)) {
    throw SceneError(file + ": /animation/frames: frame " + std::to_string(*frame) +
                     " is outside the scene's frames " + std::to_string(animation->first) + "-" +
                     std::to_string(animation->last));
  }
}

}  // namespace rayfarm
