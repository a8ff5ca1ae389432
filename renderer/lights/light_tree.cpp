#include "renderer/lights/light_tree.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace rayfarm {

namespace {

constexpr double kPiD = 3.14159265358979323846;
/// Angle by which merged cones are widened, so that rounding never leaves out a normal or a
/// spot light's edge (radians).
constexpr double kConeSlack = 1e-6;

struct D3 {
  double x, y, z;
};
D3 d3(const Vec3& v) { return {v.x, v.y, v.z}; }
double dot3(const D3& a, const D3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
D3 cross3(const D3& a, const D3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double acos_clamped(double c) { return std::acos(std::clamp(c, -1.0, 1.0)); }

/// Angle between two directions, well conditioned at 0 and pi (atan2 of |a x b| and a . b).
double angle_between(const D3& a, const D3& b) {
  const D3 c = cross3(a, b);
  return std::atan2(std::sqrt(dot3(c, c)), dot3(a, b));
}

D3 unit3(const Vec3& v) {
  const D3 d = d3(v);
  const double l = std::sqrt(dot3(d, d));
  return {d.x / l, d.y / l, d.z / l};
}

/// The smallest cone holding the cones (wa, cos_a) and (wb, cos_b), widened against rounding:
/// its half-angle is recomputed from the float axis it ends up with (its angle to each input
/// axis plus that cone's half-angle, plus kConeSlack), and its cosine rounded down by a few
/// float steps, so that no normal of either cone falls outside it, however close the axes are.
void union_cone(const Vec3& wa, float cos_a, const Vec3& wb, float cos_b, Vec3& axis,
                float& cos_o) {
  // Quick answers first (a build merges each light some 4 log2(n) times): a cone of every
  // direction holds anything, and equal cones are their own union.
  if (cos_a <= -1.f || (cos_a == cos_b && wa == wb)) {
    axis = wa, cos_o = cos_a;
    return;
  }
  if (cos_b <= -1.f) {
    axis = wb, cos_o = cos_b;
    return;
  }
  const double ta = acos_clamped(cos_a), tb = acos_clamped(cos_b);
  const D3 a = unit3(wa), b = unit3(wb);
  const double td = angle_between(a, b);
  if (std::min(td + tb, kPiD) <= ta) {
    axis = wa;
  } else if (std::min(td + ta, kPiD) <= tb) {
    axis = wb;
  } else {
    const double to = 0.5 * (ta + td + tb);
    const D3 k = cross3(a, b);
    const double k_len = std::sqrt(dot3(k, k));
    if (to + kConeSlack >= kPiD || !(k_len > 0.0)) {
      // Opposite axes, or a cone that is all directions anyway.
      axis = wa, cos_o = -1.f;
      return;
    }
    // Rotate a towards b, about their common normal, by to - ta.
    const double tr = to - ta, c = std::cos(tr), s = std::sin(tr);
    const D3 kn{k.x / k_len, k.y / k_len, k.z / k_len};
    const D3 kxa = cross3(kn, a);
    const D3 w{a.x * c + kxa.x * s, a.y * c + kxa.y * s, a.z * c + kxa.z * s};
    const double w_len = std::sqrt(dot3(w, w));
    axis = Vec3(static_cast<float>(w.x / w_len), static_cast<float>(w.y / w_len),
                static_cast<float>(w.z / w_len));
  }
  // The half-angle that the float axis needs to hold both cones.
  const D3 w = unit3(axis);
  const double need = std::max(angle_between(w, a) + ta, angle_between(w, b) + tb) + kConeSlack;
  if (need >= kPiD) {
    cos_o = -1.f;
    return;
  }
  float c = static_cast<float>(std::cos(need));
  for (int i = 0; i < 4; ++i) c = std::nextafter(c, -1.f);
  cos_o = std::max(c, -1.f);
}

/// The orientation measure of pbrt-v4's light BVH: the solid angle, weighted by cosine, into
/// which a group with these cones can emit.
double orientation_measure(const LightBounds& b) {
  const double to = acos_clamped(b.cos_o), te = acos_clamped(b.cos_e);
  const double tw = std::min(to + te, kPiD), sin_o = std::sin(to);
  return 2.0 * kPiD * (1.0 - b.cos_o) +
         0.5 * kPiD * (2.0 * tw * sin_o - std::cos(to - 2.0 * tw) - 2.0 * to * sin_o + b.cos_o);
}

double surface_area(const LightBounds& b) {
  const double ex = double(b.hi.x) - b.lo.x, ey = double(b.hi.y) - b.lo.y,
               ez = double(b.hi.z) - b.lo.z;
  return 2.0 * (ex * ey + ey * ez + ez * ex);
}

uint32_t ceil_log2(uint32_t n) {
  uint32_t bits = 0;
  while ((uint64_t{1} << bits) < n) ++bits;
  return bits;
}

}  // namespace

LightBounds merge(const LightBounds& a, const LightBounds& b) {
  LightBounds m;
  m.lo = Vec3(std::min(a.lo.x, b.lo.x), std::min(a.lo.y, b.lo.y), std::min(a.lo.z, b.lo.z));
  m.hi = Vec3(std::max(a.hi.x, b.hi.x), std::max(a.hi.y, b.hi.y), std::max(a.hi.z, b.hi.z));
  m.intensity = a.intensity + b.intensity;
  m.two_sided = a.two_sided || b.two_sided;
  m.cos_e = std::min(a.cos_e, b.cos_e);
  union_cone(a.axis, a.cos_o, b.axis, b.cos_o, m.axis, m.cos_o);
  return m;
}

LightTree::LightTree(const std::vector<LightBounds>& bounds, const std::vector<int32_t>& lights) {
  if (bounds.size() != lights.size())
    throw std::invalid_argument("light tree: one index per light's bounds");
  if (bounds.empty()) return;
  if (bounds.size() >= std::numeric_limits<uint32_t>::max() / 2)
    throw std::invalid_argument("light tree: too many lights");
  int32_t most = 0;
  for (const int32_t l : lights) {
    if (l < 0) throw std::invalid_argument("light tree: negative light index");
    most = std::max(most, l);
  }
  paths_.resize(static_cast<size_t>(most) + 1);
  nodes_.reserve(2 * bounds.size() - 1);
  std::vector<uint32_t> order(bounds.size());
  for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
  build(order, 0, static_cast<uint32_t>(order.size()), 0, 0, bounds, lights);
}

LightBounds LightTree::build(std::vector<uint32_t>& order, uint32_t begin, uint32_t end,
                             uint32_t depth, uint64_t turns, const std::vector<LightBounds>& bounds,
                             const std::vector<int32_t>& lights) {
  const uint32_t index = static_cast<uint32_t>(nodes_.size());
  nodes_.emplace_back();
  if (end - begin == 1) {
    nodes_[index].bounds = bounds[order[begin]].compact();
    nodes_[index].light = lights[order[begin]];
    paths_[lights[order[begin]]] = Path{turns, depth, true};
    depth_ = std::max(depth_, depth);
    return bounds[order[begin]];
  }
  // The node's box (its cones are not needed here: merge() of the children makes them) and its
  // lights' centroids' box.
  LightBounds all = bounds[order[begin]];
  double clo[3] = {INFINITY, INFINITY, INFINITY}, chi[3] = {-INFINITY, -INFINITY, -INFINITY};
  const auto centroid = [&](uint32_t i, int axis) {
    return 0.5 * (double(bounds[i].lo[axis]) + bounds[i].hi[axis]);
  };
  for (uint32_t i = begin; i < end; ++i) {
    const LightBounds& b = bounds[order[i]];
    all.lo =
        Vec3(std::min(all.lo.x, b.lo.x), std::min(all.lo.y, b.lo.y), std::min(all.lo.z, b.lo.z));
    all.hi =
        Vec3(std::max(all.hi.x, b.hi.x), std::max(all.hi.y, b.hi.y), std::max(all.hi.z, b.hi.z));
    for (int a = 0; a < 3; ++a) {
      clo[a] = std::min(clo[a], centroid(order[i], a));
      chi[a] = std::max(chi[a], centroid(order[i], a));
    }
  }
  // Binned surface-area-orientation heuristic over the three axes.
  constexpr int kBins = 12;
  const double extent[3] = {double(all.hi.x) - all.lo.x, double(all.hi.y) - all.lo.y,
                            double(all.hi.z) - all.lo.z};
  const double longest = std::max({extent[0], extent[1], extent[2]});
  // Degenerate boxes (point lights) still compare by a small share of the node's own area.
  const double area_floor = 1e-3 * surface_area(all) + 1e-30;
  // The orientation measure (four calls into libm) of the last cones asked: groups of lights
  // that face alike, the common case, ask for the same cones again and again.
  float last_cos_o = 2.f, last_cos_e = 2.f;
  double last_measure = 0.0;
  const auto cost = [&](const LightBounds& b, int axis) {
    if (b.cos_o != last_cos_o || b.cos_e != last_cos_e) {
      last_cos_o = b.cos_o, last_cos_e = b.cos_e;
      last_measure = orientation_measure(b);
    }
    const double kr = extent[axis] > 0.0 ? longest / extent[axis] : 1.0;
    return b.intensity * last_measure * kr * (surface_area(b) + area_floor);
  };
  const auto bin_of = [&](uint32_t light, int axis) {
    const double lo = clo[axis], hi = chi[axis];
    const double at = kBins * ((centroid(light, axis) - lo) / (hi - lo));
    return at >= kBins - 1 ? kBins - 1 : (at > 0.0 ? static_cast<int>(at) : 0);
  };
  double best_cost = INFINITY;
  int best_axis = -1, best_split = 0;
  const uint32_t count = end - begin;
  for (int axis = 0; axis < 3; ++axis) {
    if (!(chi[axis] > clo[axis])) continue;
    std::array<LightBounds, kBins> bin_bounds;
    std::array<uint32_t, kBins> bin_count{};
    for (uint32_t i = begin; i < end; ++i) {
      const int b = bin_of(order[i], axis);
      bin_bounds[b] = bin_count[b] == 0 ? bounds[order[i]] : merge(bin_bounds[b], bounds[order[i]]);
      ++bin_count[b];
    }
    // Costs of the groups below and above each boundary.
    std::array<double, kBins> below_cost{};
    LightBounds acc;
    uint32_t acc_count = 0;
    for (int b = 0; b + 1 < kBins; ++b) {
      if (bin_count[b] > 0) acc = acc_count == 0 ? bin_bounds[b] : merge(acc, bin_bounds[b]);
      acc_count += bin_count[b];
      below_cost[b] = acc_count == 0 ? INFINITY : cost(acc, axis);
    }
    acc_count = 0;
    uint32_t below_count = count;
    for (int b = kBins - 1; b >= 1; --b) {
      if (bin_count[b] > 0) acc = acc_count == 0 ? bin_bounds[b] : merge(acc, bin_bounds[b]);
      acc_count += bin_count[b];
      below_count -= bin_count[b];
      if (acc_count == 0 || below_count == 0) continue;
      // Both sides must still fit under the depth limit as balanced trees.
      if (depth + 1 + ceil_log2(std::max(acc_count, below_count)) > kMaxDepth) continue;
      const double c = below_cost[b - 1] + cost(acc, axis);
      if (c < best_cost) best_cost = c, best_axis = axis, best_split = b;
    }
  }
  uint32_t middle;
  if (best_axis >= 0) {
    middle = static_cast<uint32_t>(
        std::partition(order.begin() + begin, order.begin() + end,
                       [&](uint32_t l) { return bin_of(l, best_axis) < best_split; }) -
        order.begin());
  } else {
    // No useful split (all centroids equal, or the depth limit): halves along the longest
    // centroid axis, which keeps the tree balanced.
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (chi[a] - clo[a] > chi[axis] - clo[axis]) axis = a;
    middle = begin + count / 2;
    std::nth_element(order.begin() + begin, order.begin() + middle, order.begin() + end,
                     [&](uint32_t a, uint32_t b) {
                       const double ca = centroid(a, axis), cb = centroid(b, axis);
                       return ca < cb || (ca == cb && a < b);
                     });
  }
  // The first child follows the node; the second follows the first's subtree.
  const LightBounds first = build(order, begin, middle, depth + 1, turns, bounds, lights);
  nodes_[index].second = static_cast<uint32_t>(nodes_.size());
  const LightBounds second =
      build(order, middle, end, depth + 1, turns | (uint64_t{1} << depth), bounds, lights);
  const LightBounds both = merge(first, second);
  nodes_[index].bounds = both.compact();
  return both;
}

float LightTree::first_share(uint32_t node, const Vec3& p, const Vec3& n) const {
  double a = nodes_[node + 1].bounds.importance(p, n);
  double b = nodes_[nodes_[node].second].bounds.importance(p, n);
  a = a > 0.0 ? a : 0.0;  // also NaN
  b = b > 0.0 ? b : 0.0;
  const double total = a + b;
  if (!(total > 0.0)) return -1.f;  // neither child can reach p
  if (b == 0.0) return 1.f;
  if (a == 0.0) return 0.f;
  // Both can reach p: neither share may round to nothing (1 - share exactly 0 in float).
  return std::clamp(static_cast<float>(a / total), 0x1p-24f, 1.f - 0x1p-24f);
}

bool LightTree::choose(const Vec3& p, const Vec3& n, double u, int32_t& light,
                       float& probability) const {
  if (nodes_.empty()) return false;
  // u is remapped in double at every level: a float's 24 bits, divided by the shares along
  // a path, would leave lights below a branch of small probability unreachable.
  constexpr double kBelowOne = 0x1.fffffffffffffp-1;
  uint32_t node = 0;
  float pmf = 1.f;
  while (nodes_[node].light < 0) {
    const float share = first_share(node, p, n);
    if (share < 0.f) return false;
    if (u < share) {
      pmf *= share;
      u = std::min(u / share, kBelowOne);
      node = node + 1;
    } else {
      const float rest = 1.f - share;
      pmf *= rest;
      u = std::min((u - share) / double(rest), kBelowOne);
      node = nodes_[node].second;
    }
  }
  light = nodes_[node].light;
  probability = pmf;
  return pmf > 0.f;
}

float LightTree::probability(const Vec3& p, const Vec3& n, int32_t light) const {
  if (light < 0 || static_cast<size_t>(light) >= paths_.size() || !paths_[light].present)
    return 0.f;
  const Path& path = paths_[light];
  uint32_t node = 0;
  float pmf = 1.f;
  for (uint32_t d = 0; d < path.length; ++d) {
    const float share = first_share(node, p, n);
    if (share < 0.f) return 0.f;
    if ((path.turns >> d) & 1) {
      pmf *= 1.f - share;
      node = nodes_[node].second;
    } else {
      pmf *= share;
      node = node + 1;
    }
  }
  return pmf;
}

}  // namespace rayfarm
