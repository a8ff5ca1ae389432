#include "common/scene/gltf_animation.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace rayfarm::gltf {
namespace {

enum class Interpolation { kLinear, kStep, kCubic };

/// One channel's keys: times, and `components` numbers per key (three keys' worth per time for
/// a cubic spline: in-tangent, value, out-tangent).
struct Channel {
  int node = -1;
  std::string path;  // "translation", "rotation" or "scale"
  Interpolation interpolation = Interpolation::kLinear;
  std::vector<float> times;
  std::vector<float> values;
  int components = 3;
};

std::string at_animation(size_t a) { return "animations[" + std::to_string(a) + "]"; }

/// The channels of every animation that key a node's transform, checked.
std::vector<Channel> read_channels(const Source& src, bool warn) {
  const tinygltf::Model& model = *src.model;
  std::vector<Channel> out;
  bool warned_weights = false;
  for (size_t a = 0; a < model.animations.size(); ++a) {
    const tinygltf::Animation& anim = model.animations[a];
    for (size_t c = 0; c < anim.channels.size(); ++c) {
      const tinygltf::AnimationChannel& ch = anim.channels[c];
      const std::string where = at_animation(a) + "/channels/" + std::to_string(c);
      if (ch.target_path == "weights") {
        if (warn && !warned_weights) {
          src.warn(where,
                   "morph target weights are not supported; the meshes keep their base shape");
          warned_weights = true;
        }
        continue;
      }
      Channel channel;
      channel.path = ch.target_path;
      if (channel.path == "rotation") {
        channel.components = 4;
      } else if (channel.path != "translation" && channel.path != "scale") {
        src.fail(where + "/target/path", "unknown path \"" + ch.target_path + "\"");
      }
      if (ch.target_node < 0 || size_t(ch.target_node) >= model.nodes.size()) {
        src.fail(where + "/target/node",
                 "node " + std::to_string(ch.target_node) + " does not exist");
      }
      channel.node = ch.target_node;
      if (!model.nodes[size_t(ch.target_node)].matrix.empty()) {
        src.fail(where + "/target/node",
                 "an animated node must not have a matrix (its translation, rotation and scale "
                 "are what is animated)");
      }
      if (ch.sampler < 0 || size_t(ch.sampler) >= anim.samplers.size()) {
        src.fail(where + "/sampler", "sampler " + std::to_string(ch.sampler) + " does not exist");
      }
      const tinygltf::AnimationSampler& s = anim.samplers[size_t(ch.sampler)];
      const std::string at_sampler = at_animation(a) + "/samplers/" + std::to_string(ch.sampler);
      if (s.interpolation == "LINEAR" || s.interpolation.empty()) {
        channel.interpolation = Interpolation::kLinear;
      } else if (s.interpolation == "STEP") {
        channel.interpolation = Interpolation::kStep;
      } else if (s.interpolation == "CUBICSPLINE") {
        channel.interpolation = Interpolation::kCubic;
      } else {
        src.fail(at_sampler + "/interpolation", "unknown interpolation \"" + s.interpolation +
                                                    "\" (expected LINEAR, STEP or CUBICSPLINE)");
      }
      channel.times = read_floats(src, s.input, 1, at_sampler + "/input");
      if (channel.times.empty()) src.fail(at_sampler + "/input", "has no keys");
      for (size_t k = 0; k < channel.times.size(); ++k) {
        if (channel.times[k] < 0.f || (k > 0 && !(channel.times[k] > channel.times[k - 1]))) {
          src.fail(at_sampler + "/input",
                   "key times must be non-negative and increasing (key " + std::to_string(k) + ")");
        }
      }
      channel.values = read_floats(src, s.output, channel.components, at_sampler + "/output");
      const size_t per_key = channel.interpolation == Interpolation::kCubic ? 3 : 1;
      if (channel.values.size() != channel.times.size() * per_key * size_t(channel.components)) {
        src.fail(at_sampler + "/output",
                 "has " + std::to_string(channel.values.size() / size_t(channel.components)) +
                     " values for " + std::to_string(channel.times.size()) + " keys (expected " +
                     std::to_string(channel.times.size() * per_key) + ")");
      }
      out.push_back(std::move(channel));
    }
  }
  return out;
}

/// The value (components numbers) of key k's element `which` (0 for LINEAR and STEP; for a
/// cubic spline 0 in-tangent, 1 value, 2 out-tangent).
const float* key_value(const Channel& c, size_t k, size_t which) {
  const size_t per_key = c.interpolation == Interpolation::kCubic ? 3 : 1;
  return &c.values[(k * per_key + which) * size_t(c.components)];
}

std::vector<double> normalized(std::vector<double> q) {
  double len = 0.0;
  for (double x : q) len += x * x;
  len = std::sqrt(len);
  if (len > 0.0) {
    for (double& x : q) x /= len;
  }
  return q;
}

std::vector<double> evaluate(const Channel& c, double t) {
  const size_t n = c.times.size();
  const size_t value = c.interpolation == Interpolation::kCubic ? 1 : 0;
  const auto at_key = [&](size_t k) {
    const float* v = key_value(c, k, value);
    return std::vector<double>(v, v + c.components);
  };
  if (t <= c.times.front()) return at_key(0);
  if (t >= c.times.back()) return at_key(n - 1);
  // The segment [k, k + 1] holding t, compared in double as the ends were (a key time in float
  // may lie just above the double time of the same frame).
  const auto after = std::upper_bound(c.times.begin(), c.times.end(), t,
                                      [](double a, float b) { return a < double(b); });
  const size_t k = std::min(size_t(after - c.times.begin()), n - 1) - 1;
  if (c.interpolation == Interpolation::kStep) return at_key(k);
  const double t0 = c.times[k], t1 = c.times[k + 1], h = t1 - t0;
  const double s = std::clamp((t - t0) / h, 0.0, 1.0);
  std::vector<double> a = at_key(k), b = at_key(k + 1), out(size_t(c.components));
  if (c.interpolation == Interpolation::kCubic) {
    const float* out_tangent = key_value(c, k, 2);
    const float* in_tangent = key_value(c, k + 1, 0);
    const double s2 = s * s, s3 = s2 * s;
    for (size_t i = 0; i < out.size(); ++i) {
      out[i] = (2 * s3 - 3 * s2 + 1) * a[i] + (s3 - 2 * s2 + s) * h * out_tangent[i] +
               (-2 * s3 + 3 * s2) * b[i] + (s3 - s2) * h * in_tangent[i];
    }
    return c.path == "rotation" ? normalized(out) : out;
  }
  if (c.path != "rotation") {
    for (size_t i = 0; i < out.size(); ++i) out[i] = a[i] + (b[i] - a[i]) * s;
    return out;
  }
  // Spherical linear interpolation, the short way round.
  a = normalized(a);
  b = normalized(b);
  double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
  if (dot < 0.0) {
    for (double& x : b) x = -x;
    dot = -dot;
  }
  if (dot > 0.9995) {  // nearly equal: linear is exact enough and avoids dividing by ~0
    for (size_t i = 0; i < 4; ++i) out[i] = a[i] + (b[i] - a[i]) * s;
    return normalized(out);
  }
  const double theta = std::acos(std::min(dot, 1.0));
  const double wa = std::sin((1 - s) * theta) / std::sin(theta);
  const double wb = std::sin(s * theta) / std::sin(theta);
  for (size_t i = 0; i < 4; ++i) out[i] = wa * a[i] + wb * b[i];
  return normalized(out);
}

}  // namespace

double animation_duration(const Source& src) {
  double end = 0.0;
  for (const Channel& c : read_channels(src, false)) end = std::max(end, double(c.times.back()));
  return end;
}

void apply_animations(const Source& src, tinygltf::Model& model, double seconds) {
  for (const Channel& c : read_channels(src, true)) {
    tinygltf::Node& node = model.nodes[size_t(c.node)];
    const std::vector<double> v = evaluate(c, seconds);
    if (c.path == "translation") {
      node.translation = v;
    } else if (c.path == "rotation") {
      node.rotation = v;
    } else {
      node.scale = v;
    }
  }
}

}  // namespace rayfarm::gltf
