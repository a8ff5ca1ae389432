#pragma once
// What the BSDF tests share: Pearson's chi-square test with its p-value, directions on the sphere,
// and a quadrature over bins of (cos theta, phi) for integrating pdfs and BSDFs.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "common/math/vec3.h"
#include "renderer/samplers/rng.h"

namespace rayfarm::testing {

inline constexpr double kTwoPi = 6.283185307179586;

// ----------------------------------------------------------------------------------------------
// Statistics

/// Regularised upper incomplete gamma function Q(a, x): a series below a + 1, a continued
/// fraction (modified Lentz) above.
inline double gamma_q(double a, double x) {
  if (x <= 0.0) return 1.0;
  const double log_prefix = a * std::log(x) - x - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 100000 && term > 1e-17 * sum; ++n) {
      term *= x / (a + n);
      sum += term;
    }
    return std::max(0.0, 1.0 - sum * std::exp(log_prefix));
  }
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 100000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::fabs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::fabs(delta - 1.0) < 1e-15) break;
  }
  return std::exp(log_prefix) * h;
}

/// Probability that a chi-square variable with `dof` degrees of freedom exceeds x.
inline double chi_square_survival(double x, int dof) { return gamma_q(0.5 * dof, 0.5 * x); }

struct ChiSquareResult {
  double statistic = 0.0;
  int dof = 0;
  double p_value = 1.0;
  std::string note;  // why the test failed outright, if it did
};

/// Pearson's test of observed counts against expected counts (same total). Cells expected to
/// receive fewer than 5 samples are pooled (with the next smallest cells until the pool reaches 5).
inline ChiSquareResult chi_square_test(const std::vector<double>& observed,
                                       const std::vector<double>& expected) {
  ChiSquareResult r;
  std::vector<size_t> order(expected.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return expected[a] < expected[b]; });
  double pool_obs = 0.0, pool_exp = 0.0;
  int cells = 0;
  for (const size_t i : order) {
    if (expected[i] <= 0.0 && observed[i] > 0.0) {
      r.note = "samples in a cell of zero probability";
      r.p_value = 0.0;
      return r;
    }
    // In increasing order of expectation: a cell joins the pool, which closes once it reaches 5
    // (so a cell expected to reach 5 on its own is a pool of one).
    pool_obs += observed[i];
    pool_exp += expected[i];
    if (pool_exp >= 5.0) {
      r.statistic += (pool_obs - pool_exp) * (pool_obs - pool_exp) / pool_exp;
      ++cells;
      pool_obs = pool_exp = 0.0;
    }
  }
  if (pool_exp > 0.0) {  // a remainder below 5 is left only when all cells together are below 5
    r.statistic += (pool_obs - pool_exp) * (pool_obs - pool_exp) / pool_exp;
    ++cells;
  }
  r.dof = cells - 1;
  r.p_value = r.dof > 0 ? chi_square_survival(r.statistic, r.dof) : 1.0;
  return r;
}

// ----------------------------------------------------------------------------------------------
// Directions and quadrature

inline Vec3 spherical(double theta, double phi, int side) {
  return {static_cast<float>(std::sin(theta) * std::cos(phi)),
          static_cast<float>(std::sin(theta) * std::sin(phi)),
          static_cast<float>(side * std::cos(theta))};
}

inline Vec3 uniform_sphere(Pcg32& rng) {
  const double z = 1.0 - 2.0 * rng.next_float();
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  const double phi = kTwoPi * rng.next_float();
  return {static_cast<float>(r * std::cos(phi)), static_cast<float>(r * std::sin(phi)),
          static_cast<float>(z)};
}

/// A grid of bins uniform in cos(theta) and phi over part of one hemisphere of the local frame
/// (side +1: z > 0, side -1: z < 0; theta measured from the pole of that side).
struct AngleGrid {
  double cos_lo = 0.0, cos_hi = 1.0;
  int cos_bins = 10;
  double phi_lo = 0.0, phi_hi = kTwoPi;
  int phi_bins = 20;
  int side = 1;

  int bins() const { return cos_bins * phi_bins; }

  /// The bin holding direction w, or -1 when w is not on the grid.
  int bin_of(const Vec3& w) const {
    const double c = side * double(w.z);
    double phi = std::atan2(double(w.y), double(w.x));
    if (phi < 0.0) phi += kTwoPi;
    if (c < cos_lo || c > cos_hi || phi < phi_lo || phi > phi_hi) return -1;
    const int i = std::min(cos_bins - 1, int((c - cos_lo) / (cos_hi - cos_lo) * cos_bins));
    const int j = std::min(phi_bins - 1, int((phi - phi_lo) / (phi_hi - phi_lo) * phi_bins));
    return i * phi_bins + j;
  }
};

/// Visits the nodes of a quadrature over every bin of `grid`: f(bin, w, weight) such that the sum
/// of weight * g(w) over a bin approximates the integral of g over that bin (solid angle). Each bin
/// is cut into cells of at most `h` radians in theta and in phi, each with 2 x 2 Gauss-Legendre
/// nodes, so the rule is exact to fourth order in h.
template <class F>
void for_each_node(const AngleGrid& grid, double h, F&& f) {
  const double gl = 0.5 / std::sqrt(3.0);  // Gauss-Legendre nodes at mid +- gl * width
  struct PhiNode {
    int bin;
    double cos_phi, sin_phi, weight;
  };
  std::vector<PhiNode> phi_nodes;
  const double dphi = (grid.phi_hi - grid.phi_lo) / grid.phi_bins;
  const int n_phi = std::max(1, int(std::ceil(dphi / h)));
  const double w_phi = dphi / n_phi;
  for (int j = 0; j < grid.phi_bins; ++j) {
    for (int b = 0; b < n_phi; ++b) {
      for (const double offset : {-gl, gl}) {
        const double phi = grid.phi_lo + j * dphi + (b + 0.5 + offset) * w_phi;
        phi_nodes.push_back({j, std::cos(phi), std::sin(phi), 0.5 * w_phi});
      }
    }
  }
  const double dc = (grid.cos_hi - grid.cos_lo) / grid.cos_bins;
  for (int i = 0; i < grid.cos_bins; ++i) {
    const double theta_lo = std::acos(std::min(1.0, grid.cos_lo + (i + 1) * dc));
    const double theta_hi = std::acos(std::min(1.0, grid.cos_lo + i * dc));
    const int n_theta = std::max(1, int(std::ceil((theta_hi - theta_lo) / h)));
    const double w_theta = (theta_hi - theta_lo) / n_theta;
    for (int a = 0; a < n_theta; ++a) {
      for (const double offset : {-gl, gl}) {
        const double theta = theta_lo + (a + 0.5 + offset) * w_theta;
        const double sin_t = std::sin(theta);
        const auto z = static_cast<float>(grid.side * std::cos(theta));
        const double ring = 0.5 * w_theta * sin_t;
        for (const PhiNode& p : phi_nodes) {
          const Vec3 w{static_cast<float>(sin_t * p.cos_phi), static_cast<float>(sin_t * p.sin_phi),
                       z};
          f(i * grid.phi_bins + p.bin, w, ring * p.weight);
        }
      }
    }
  }
}

}  // namespace rayfarm::testing
