#include "renderer/pixel_filter.h"

#include <algorithm>
#include <cmath>

#include "renderer/bsdfs/gauss_legendre.h"

namespace rayfarm {

namespace {

constexpr double kPiD = 3.14159265358979323846;

double sinc(double x) { return std::fabs(x) < 1e-9 ? 1.0 : std::sin(x) / x; }

/// Integral of g over [a, b] by 16-point Gauss-Legendre on pieces no longer than 1/16 of a pixel,
/// split at the whole and half pixel offsets where the filters have kinks (Mitchell's knots at
/// +-1, the tent's and the clipped windows' at 0 and half pixels), and at the steps of a
/// tabulated filter (multiples of `step`; 0: none). Accurate to about 1e-14 relative for the
/// smooth pieces every filter here is made of.
template <class G>
double integrate(const G& g, double a, double b, double step) {
  static const GaussLegendre<16> rule;
  if (!(b > a)) return 0.0;
  double total = 0.0, lo = a;
  while (lo < b) {
    // The next half-pixel knot above lo, the next step, then at most 1/16 of a pixel.
    const double knot = (std::floor(lo * 2.0) + 1.0) / 2.0;
    double next_step = INFINITY;
    if (step > 0.0) {
      next_step = step * (std::floor(lo / step) + 1.0);
      if (!(next_step > lo)) next_step = lo + step;
    }
    const double hi = std::min({b, knot, next_step, lo + 1.0 / 16.0});
    double piece = 0.0;
    for (int k = 0; k < 16; ++k) piece += rule.w[k] * g(lo + (hi - lo) * rule.x[k]);
    total += piece * (hi - lo);
    lo = hi;
  }
  return total;
}

}  // namespace

double filter_value(const PixelFilter& f, double x) {
  const double r = f.radius;
  double ax = std::fabs(x);
  if (ax > r) return 0.0;
  if (f.steps > 0) {  // Mitsuba's table: the value at the inner end of x's step, 0 from r on
    const double step = std::floor(ax * f.steps / r);
    if (step >= f.steps) return 0.0;
    ax = r * step / f.steps;
    x = x < 0.0 ? -ax : ax;
  }
  switch (f.type) {
    case FilterType::kBox:
      return 1.0;
    case FilterType::kTent:
      return std::max(0.0, 1.0 - ax / r);
    case FilterType::kGaussian: {
      const double alpha = -1.0 / (2.0 * double(f.stddev) * f.stddev);
      return std::max(0.0, std::exp(alpha * ax * ax) - std::exp(alpha * r * r));
    }
    case FilterType::kMitchell: {
      const double b = f.b, c = f.c, x2 = ax * ax, x3 = x2 * ax;
      const double v = ax < 1.0
                           ? (12 - 9 * b - 6 * c) * x3 + (-18 + 12 * b + 6 * c) * x2 + (6 - 2 * b)
                           : (-b - 6 * c) * x3 + (6 * b + 30 * c) * x2 + (-12 * b - 48 * c) * ax +
                                 (8 * b + 24 * c);
      return v / 6.0;
    }
    case FilterType::kLanczos:
      return sinc(kPiD * ax) * sinc(kPiD * ax / r);
    case FilterType::kBlackmanHarris: {
      const double v = 2.0 * kPiD * (x / (2.0 * r) + 0.5);
      return 0.35875 - 0.48829 * std::cos(v) + 0.14128 * std::cos(2 * v) -
             0.01168 * std::cos(3 * v);
    }
  }
  return 0.0;
}

FilterSampler::FilterSampler(const PixelFilter& filter, FilmSize film)
    : filter_(filter), pixel_box_(filter.pixel_box()) {
  if (pixel_box_) return;
  // The readers keep the radius within [1e-3, 8] pixels; a description that did not would make
  // empty bins, so it is held there here too.
  radius_ = std::clamp(std::isfinite(filter.radius) ? double(filter.radius) : 0.5, 1e-3,
                       double(kMaxFilterRadius));
  filter_.radius = static_cast<float>(radius_);
  // A tabulated filter's steps fall on bin edges (a whole number of bins per step, from both
  // ends), so that a bin's density is the filter's own there and its weight 1.
  bins_ = kBins;
  if (filter.steps > 0 && filter.steps <= 4096)
    bins_ = int(2 * filter.steps) *
            std::max(1, (kBins + int(2 * filter.steps) - 1) / int(2 * filter.steps));
  bin_ = 2.0 * radius_ / bins_;
  step_ = filter.steps > 0 ? radius_ / filter.steps : 0.0;
  mass_.resize(bins_);
  cumulative_.assign(bins_ + 1, 0.0);
  signed_.assign(bins_ + 1, 0.0);
  const auto f = [&](double x) { return filter_value(filter_, x); };
  const auto abs_f = [&](double x) { return std::fabs(filter_value(filter_, x)); };
  for (int i = 0; i < bins_; ++i) {
    const double lo = -radius_ + i * bin_, hi = i + 1 == bins_ ? radius_ : lo + bin_;
    mass_[i] = integrate(abs_f, lo, hi, step_);
    cumulative_[i + 1] = cumulative_[i] + mass_[i];
    signed_[i + 1] = signed_[i] + integrate(f, lo, hi, step_);
  }
  full_ = window(-radius_, radius_);
  columns_ = make_axis(film.width);
  rows_ = make_axis(film.height);
}

double FilterSampler::cdf(double x) const {
  if (x <= -radius_) return 0.0;
  if (x >= radius_) return cumulative_.back();
  const int i = std::min(bins_ - 1, static_cast<int>((x + radius_) / bin_));
  return cumulative_[i] + mass_[i] * ((x + radius_) - i * bin_) / bin_;
}

double FilterSampler::signed_integral(double x) const {
  if (x <= -radius_) return 0.0;
  if (x >= radius_) return signed_.back();
  const int i = std::min(bins_ - 1, static_cast<int>((x + radius_) / bin_));
  const double lo = -radius_ + i * bin_;
  return signed_[i] + integrate([&](double t) { return filter_value(filter_, t); }, lo, x, step_);
}

FilterSampler::Window FilterSampler::window(double a, double b) const {
  return {a, b, cdf(a), cdf(b), integral(a, b)};
}

FilterSampler::Axis FilterSampler::make_axis(uint32_t length) const {
  Axis axis;
  axis.length = length;
  if (filter_.sample_border || length == 0) return axis;
  // Pixel i's centre lies i + 0.5 from the first edge: its window is cut when that is below the
  // radius. Pixels cut at both edges (a film narrower than the filter) are all in `head`.
  const uint32_t cut = std::min<uint32_t>(length, static_cast<uint32_t>(std::ceil(radius_ - 0.5)));
  const auto window_at = [&](uint32_t i) {
    const double centre = i + 0.5;
    return window(std::max(-radius_, -centre), std::min(radius_, double(length) - centre));
  };
  const uint32_t head = 2 * cut >= length ? length : cut;
  for (uint32_t i = 0; i < head; ++i) axis.head.push_back(window_at(i));
  if (head < length)
    for (uint32_t k = 0; k < cut; ++k) axis.tail.push_back(window_at(length - 1 - k));
  return axis;
}

const FilterSampler::Window& FilterSampler::window_of(const Axis& axis, uint32_t i) const {
  if (i < axis.head.size()) return axis.head[i];
  const uint32_t from_end = axis.length - 1 - i;
  if (from_end < axis.tail.size()) return axis.tail[from_end];
  return full_;
}

FilterSampler::Offset FilterSampler::sample(const Axis& axis, uint32_t i, float u) const {
  const double centre = i + 0.5;
  if (pixel_box_) return {static_cast<float>(i + double(u)), 1.f};
  const Window& w = window_of(axis, i);
  // Invert the table's cumulative mass at t, within the window.
  const double t = w.cdf_a + double(u) * (w.cdf_b - w.cdf_a);
  int k = static_cast<int>(std::upper_bound(cumulative_.begin(), cumulative_.end(), t) -
                           cumulative_.begin()) -
          1;
  const int first = std::min(bins_ - 1, static_cast<int>((w.a + radius_) / bin_));
  const int last = std::min(bins_ - 1, static_cast<int>((w.b + radius_) / bin_));
  k = std::clamp(k, first, last);
  while (k < last && mass_[k] <= 0.0) ++k;  // an empty bin is never chosen
  if (mass_[k] <= 0.0 || !(w.integral > 0.0)) return {static_cast<float>(centre), 0.f};
  const double lo = -radius_ + k * bin_;
  double d = lo + (t - cumulative_[k]) / mass_[k] * bin_;
  d = std::clamp(d, std::max(w.a, lo), std::min(w.b, lo + bin_));
  // p(d) = (mass_k / bin) / (cdf_b - cdf_a); weight f(d) / (p(d) F_ab).
  const double weight =
      filter_value(filter_, d) * bin_ * (w.cdf_b - w.cdf_a) / (mass_[k] * w.integral);
  return {static_cast<float>(centre + d), static_cast<float>(weight)};
}

}  // namespace rayfarm
