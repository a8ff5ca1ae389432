#pragma once
// Pixel reconstruction filters by importance sampling (Scene::filter; docs/scene-format.md,
// "Film"). On each axis a sample's offset d from the pixel's centre is drawn from a tabulated
// density p close to |f| (512 equal bins over [-radius, radius], each bin's share its integral of
// |f|, uniform within the bin), and weighed by w = f(d) / (p(d) F), F the filter's integral. Then
// E[w L(d)] = integral of f L / F exactly, whatever the table's resolution: the pixel is the image
// through the normalised filter. Within a bin w follows f's slope around its mean of 1 (a
// Gaussian's from 0.92 to 1.07, a tent's from 0.57 to 1.24 in its outermost bins, where f falls to
// 0); a tabulated filter's steps fall on bin edges, so its w is 1. For Mitchell and Lanczos w
// carries the lobe's sign. The two axes are independent (the filter is separable) and the
// sample's weight is their product.
//
// With sample_border false the filter of a pixel whose support crosses the image's edge is cut
// there and renormalised (its own window [a, b] and integral F_ab), as Mitsuba weighs the samples
// that land inside the image only.
//
// The offsets depend on the sample's numbers and the pixel alone, so tiles, passes and the farm's
// images are unchanged by a filter. The box of the pixel's own area is not tabulated: its samples
// land where they always did, with weight 1, so scenes without a filter keep their bits.
#include <cstdint>
#include <vector>

#include "common/scene/scene.h"

namespace rayfarm {

/// The filter's value at offset x from the pixel's centre (unnormalised; 0 beyond the radius).
double filter_value(const PixelFilter& filter, double x);

class FilterSampler {
 public:
  /// Bins of the table over [-radius, radius] (a tabulated filter: the next multiple of twice its
  /// steps).
  static constexpr int kBins = 512;

  FilterSampler(const PixelFilter& filter, FilmSize film);

  /// The box of the pixel's own area: sample positions are the pixel's numbers as they are.
  bool pixel_box() const { return pixel_box_; }

  struct Offset {
    float position;  ///< along the axis, in film pixels (the pixel's centre is index + 0.5)
    float weight;    ///< f / (p F) on this axis
  };
  /// The sample of pixel column `x` drawn from the number u in [0, 1).
  Offset sample_x(uint32_t x, float u) const { return sample(columns_, x, u); }
  /// The sample of pixel row `y` drawn from u.
  Offset sample_y(uint32_t y, float u) const { return sample(rows_, y, u); }

  /// The signed integral of the filter over [a, b] (offsets within [-radius, radius]).
  double integral(double a, double b) const { return signed_integral(b) - signed_integral(a); }

 private:
  /// A pixel's window [a, b] of offsets, the table's cumulative mass at its ends, and the filter's
  /// integral over it.
  struct Window {
    double a, b, cdf_a, cdf_b, integral;
  };
  /// The windows of one axis: every pixel's is the whole support but those of the first and last
  /// few pixels when the filter is cut at the image's edge.
  struct Axis {
    uint32_t length = 0;
    std::vector<Window> head, tail;  ///< pixels 0, 1, ... and length - 1, length - 2, ...
  };

  Axis make_axis(uint32_t length) const;
  Window window(double a, double b) const;
  const Window& window_of(const Axis& axis, uint32_t i) const;
  Offset sample(const Axis& axis, uint32_t i, float u) const;
  double cdf(double x) const;              ///< cumulative table mass from -radius to x
  double signed_integral(double x) const;  ///< integral of f from -radius to x

  PixelFilter filter_;
  bool pixel_box_;
  int bins_ = kBins;
  double radius_ = 0.5, bin_ = 1.0;
  double step_ = 0.0;               ///< a tabulated filter's step (PixelFilter::steps), else 0
  std::vector<double> mass_;        ///< integral of |f| over each bin
  std::vector<double> cumulative_;  ///< bins_ + 1 running sums of mass_
  std::vector<double> signed_;      ///< bins_ + 1 running integrals of f
  Window full_{};
  Axis columns_, rows_;
};

}  // namespace rayfarm
