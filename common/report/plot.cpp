#include "common/report/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include <fmt/format.h>

#include "common/image/png.h"
#include "common/report/bitmap_font.h"

namespace rayfarm {
namespace {

// Sizes, in pixels.
constexpr int kMinWidth = 200, kMinHeight = 150, kMaxSide = 8192;
constexpr int kMarginLeft = 72, kMarginRight = 16, kMarginTop = 34, kMarginBottom = 46;
constexpr int kDashOn = 8, kDashPeriod = 13;  // dashes of 8 px every 13 px along a line
constexpr int kMarkerRadius = 3;
constexpr int kLegendRow = 14;
constexpr int kLegendSample = 24;        // length of the line drawn beside a legend entry
constexpr int kMinDecadeLabelGap = 44;   // x: pixels between two decade labels, at least
constexpr int kMinDecadeLabelGapY = 16;  // y
constexpr int kMinorGridDecade = 60;     // minor grid lines only when a decade is this long

// Only values in this range have a place on the axes (their decades are representable).
constexpr double kLogLimit = 300.0;

constexpr PlotColor kBackground{255, 255, 255};
constexpr PlotColor kInk{25, 25, 25};
constexpr PlotColor kFrame{80, 80, 80};
constexpr PlotColor kMajorGrid{210, 210, 210};
constexpr PlotColor kMinorGrid{236, 236, 236};

bool drawable(const PlotPoint& p) {
  if (!(std::isfinite(p.first) && std::isfinite(p.second) && p.first > 0 && p.second > 0)) {
    return false;
  }
  const double lx = std::log10(p.first), ly = std::log10(p.second);
  return std::abs(lx) <= kLogLimit && std::abs(ly) <= kLogLimit;
}

/// The whole decades [lo, hi] (exponents) that cover [min_log, max_log]; at least one decade.
std::pair<int, int> decade_range(double min_log, double max_log) {
  constexpr double kSlack = 1e-9;  // log10(1e-3) may come out a hair below -3
  int lo = static_cast<int>(std::floor(min_log + kSlack));
  int hi = static_cast<int>(std::ceil(max_log - kSlack));
  if (hi <= lo) hi = lo + 1;
  return {lo, hi};
}

std::pair<int, int> width_height(int width, int height) {
  return {std::clamp(width, kMinWidth, kMaxSide), std::clamp(height, kMinHeight, kMaxSide)};
}

/// An RGB raster with bounds-checked drawing and an optional clip rectangle.
class Canvas {
 public:
  Canvas(int width, int height) : image_{width, height, {}} {
    image_.rgb.resize(size_t(width) * size_t(height) * 3);
    for (size_t i = 0; i < image_.rgb.size(); i += 3) {
      std::copy(kBackground.begin(), kBackground.end(), image_.rgb.begin() + long(i));
    }
    clip_ = {0, 0, width - 1, height - 1};
  }

  void set(int x, int y, const PlotColor& c) {
    if (x < clip_[0] || y < clip_[1] || x > clip_[2] || y > clip_[3]) return;
    const size_t i = (size_t(y) * size_t(image_.width) + size_t(x)) * 3;
    std::copy(c.begin(), c.end(), image_.rgb.begin() + long(i));
  }
  void fill(int x0, int y0, int x1, int y1, const PlotColor& c) {
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) set(x, y, c);
    }
  }
  void outline(int x0, int y0, int x1, int y1, const PlotColor& c) {
    fill(x0, y0, x1, y0, c);
    fill(x0, y1, x1, y1, c);
    fill(x0, y0, x0, y1, c);
    fill(x1, y0, x1, y1, c);
  }
  /// Drawing outside [x0, x1] x [y0, y1] is dropped until unclip().
  void clip(int x0, int y0, int x1, int y1) {
    clip_ = {std::max(x0, 0), std::max(y0, 0), std::min(x1, image_.width - 1),
             std::min(y1, image_.height - 1)};
  }
  void unclip() { clip_ = {0, 0, image_.width - 1, image_.height - 1}; }

  PlotImage take() { return std::move(image_); }

 private:
  PlotImage image_;
  std::array<int, 4> clip_{};
};

/// How lines are drawn: colour, a 2x2 pixel brush, solid or dashed. `phase` carries the dash
/// pattern from one segment of a polyline to the next.
struct Pen {
  PlotColor rgb;
  bool dashed = false;
  double phase = 0.0;
};

/// A line from (x0, y0) to (x1, y1) (pixels, rounded to the nearest), Bresenham's algorithm.
void draw_line(Canvas& canvas, double fx0, double fy0, double fx1, double fy1, Pen& pen) {
  int x0 = static_cast<int>(std::lround(fx0)), y0 = static_cast<int>(std::lround(fy0));
  const int x1 = static_cast<int>(std::lround(fx1)), y1 = static_cast<int>(std::lround(fy1));
  const int dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0);
  const int sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
  const int steps = std::max(dx, -dy);
  const double length = std::hypot(double(dx), double(dy));
  const double per_step = steps > 0 ? length / steps : 0.0;
  int error = dx + dy;
  for (int step = 0;; ++step) {
    const double along = pen.phase + step * per_step;
    if (!pen.dashed || std::fmod(along, double(kDashPeriod)) < kDashOn) {
      canvas.fill(x0, y0, x0 + 1, y0 + 1, pen.rgb);
    }
    if (x0 == x1 && y0 == y1) break;
    const int e2 = 2 * error;
    if (e2 >= dy) {
      error += dy;
      x0 += sx;
    }
    if (e2 <= dx) {
      error += dx;
      y0 += sy;
    }
  }
  pen.phase += length;
}

/// Clips the segment to the rectangle (Liang-Barsky); false when none of it is inside.
bool clip_segment(double& x0, double& y0, double& x1, double& y1, double left, double top,
                  double right, double bottom) {
  double t0 = 0.0, t1 = 1.0;
  const double dx = x1 - x0, dy = y1 - y0;
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {x0 - left, right - x0, y0 - top, bottom - y0};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0.0) {
      if (q[i] < 0.0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0.0) {
      t0 = std::max(t0, t);
    } else {
      t1 = std::min(t1, t);
    }
  }
  if (t0 > t1) return false;
  const double ax = x0 + t0 * dx, ay = y0 + t0 * dy;
  x1 = x0 + t1 * dx;
  y1 = y0 + t1 * dy;
  x0 = ax;
  y0 = ay;
  return true;
}

/// A filled marker centred at (x, y); its shape tells series apart where colours are not enough:
/// square, diamond, triangle, circle, in the order of the series.
void draw_marker(Canvas& canvas, double fx, double fy, size_t shape, const PlotColor& c) {
  const int cx = static_cast<int>(std::lround(fx)), cy = static_cast<int>(std::lround(fy));
  const int r = kMarkerRadius + (shape % 4 == 1 ? 1 : 0);
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      bool inside = true;
      switch (shape % 4) {
        case 1:
          inside = std::abs(dx) + std::abs(dy) <= r;
          break;
        case 2:
          inside = 2 * std::abs(dx) <= dy + r + 1;
          break;
        case 3:
          inside = dx * dx + dy * dy <= r * r + 1;
          break;
        default:
          break;
      }
      if (inside) canvas.set(cx + dx, cy + dy, c);
    }
  }
}

/// Width in pixels of `text` drawn at `scale`.
int text_width(std::string_view text, int scale) {
  return text.empty() ? 0 : (int(text.size()) * kGlyphAdvance - 1) * scale;
}

/// Draws `text` with its top-left corner at (x, y); `vertical` turns it a quarter counter-clockwise
/// (reading upwards) with (x, y) at its bottom-left corner.
void draw_text(Canvas& canvas, int x, int y, std::string_view text, const PlotColor& c,
               int scale = 1, bool vertical = false) {
  for (size_t i = 0; i < text.size(); ++i) {
    const GlyphRows& rows = glyph(text[i]);
    for (int gy = 0; gy < kGlyphHeight; ++gy) {
      for (int gx = 0; gx < kGlyphWidth; ++gx) {
        if (!(rows[size_t(gy)] & (0x10 >> gx))) continue;
        const int along = (int(i) * kGlyphAdvance + gx) * scale;
        for (int sy = 0; sy < scale; ++sy) {
          for (int sx = 0; sx < scale; ++sx) {
            if (vertical) {
              canvas.set(x + gy * scale + sy, y - along - sx, c);
            } else {
              canvas.set(x + along + sx, y + gy * scale + sy, c);
            }
          }
        }
      }
    }
  }
}

std::string decade_label(int exponent) { return fmt::format("1e{}", exponent); }

/// Every how many decades a label fits, given the pixels per decade and the room a label needs.
int label_step(double pixels_per_decade, int room) {
  return std::max(1, static_cast<int>(std::ceil(room / std::max(pixels_per_decade, 1e-9))));
}

void draw_grid_and_ticks(Canvas& canvas, const PlotAxes& axes) {
  const int x_lo = int(std::lround(std::log10(axes.x_min)));
  const int x_hi = int(std::lround(std::log10(axes.x_max)));
  const int y_lo = int(std::lround(std::log10(axes.y_min)));
  const int y_hi = int(std::lround(std::log10(axes.y_max)));
  const double x_decade = double(axes.right - axes.left) / (x_hi - x_lo);
  const double y_decade = double(axes.bottom - axes.top) / (y_hi - y_lo);

  // Minor grid lines at 2..9 times each decade, where decades are long enough to show them.
  for (int e = x_lo; e < x_hi && x_decade >= kMinorGridDecade; ++e) {
    for (int m = 2; m <= 9; ++m) {
      const int x = int(std::lround(axes.to_pixel(m * std::pow(10.0, e), axes.y_min).first));
      canvas.fill(x, axes.top, x, axes.bottom, kMinorGrid);
    }
  }
  for (int e = y_lo; e < y_hi && y_decade >= kMinorGridDecade; ++e) {
    for (int m = 2; m <= 9; ++m) {
      const int y = int(std::lround(axes.to_pixel(axes.x_min, m * std::pow(10.0, e)).second));
      canvas.fill(axes.left, y, axes.right, y, kMinorGrid);
    }
  }

  // Decades: a grid line each, a label every `step` of them (always the first one).
  const int x_step = label_step(x_decade, kMinDecadeLabelGap);
  for (int e = x_lo; e <= x_hi; ++e) {
    const int x = axes.left + int(std::lround((e - x_lo) * x_decade));
    canvas.fill(x, axes.top, x, axes.bottom, kMajorGrid);
    canvas.fill(x, axes.bottom + 1, x, axes.bottom + 4, kFrame);
    if ((e - x_lo) % x_step != 0) continue;
    const std::string label = decade_label(e);
    draw_text(canvas, x - text_width(label, 1) / 2, axes.bottom + 7, label, kInk);
  }
  const int y_step = label_step(y_decade, kMinDecadeLabelGapY);
  for (int e = y_lo; e <= y_hi; ++e) {
    const int y = axes.bottom - int(std::lround((e - y_lo) * y_decade));
    canvas.fill(axes.left, y, axes.right, y, kMajorGrid);
    canvas.fill(axes.left - 4, y, axes.left - 1, y, kFrame);
    if ((e - y_lo) % y_step != 0) continue;
    const std::string label = decade_label(e);
    draw_text(canvas, axes.left - 7 - text_width(label, 1), y - kGlyphHeight / 2, label, kInk);
  }
}

/// The slope line across the plotting area, dashed, clipped to it.
void draw_slope_line(Canvas& canvas, const PlotAxes& axes, const SlopeLine& line) {
  if (!drawable(line.through) || !std::isfinite(line.slope)) return;
  const double lx0 = std::log10(line.through.first), ly0 = std::log10(line.through.second);
  // The line's ends at the left and right of the plot, in pixels; computed in logarithms, since
  // its y there may lie far outside the axes.
  const double y_decades = std::log10(axes.y_max) - std::log10(axes.y_min);
  const auto end = [&](double x) {
    const double ly = ly0 + line.slope * (std::log10(x) - lx0);
    const double py =
        axes.bottom - (ly - std::log10(axes.y_min)) / y_decades * (axes.bottom - axes.top);
    return std::pair{axes.to_pixel(x, axes.y_min).first, py};
  };
  auto [x0, y0] = end(axes.x_min);
  auto [x1, y1] = end(axes.x_max);
  if (!std::isfinite(y0) || !std::isfinite(y1)) return;
  if (!clip_segment(x0, y0, x1, y1, axes.left, axes.top, axes.right, axes.bottom)) return;
  canvas.clip(axes.left, axes.top, axes.right, axes.bottom);
  Pen pen{line.rgb, true};
  draw_line(canvas, x0, y0, x1, y1, pen);
  canvas.unclip();
}

void draw_series(Canvas& canvas, const PlotAxes& axes, const PlotSeries& series, size_t index) {
  Pen pen{series.rgb, series.dashed};
  bool joined = false;  // whether the previous point is drawable, to join this one to it
  std::pair<double, double> previous{0.0, 0.0};
  for (const PlotPoint& p : series.points) {
    if (!drawable(p)) {
      joined = false;  // a gap in the line
      continue;
    }
    const auto at = axes.to_pixel(p.first, p.second);
    if (joined) draw_line(canvas, previous.first, previous.second, at.first, at.second, pen);
    previous = at;
    joined = true;
  }
  if (!series.markers) return;
  for (const PlotPoint& p : series.points) {
    if (!drawable(p)) continue;
    const auto [x, y] = axes.to_pixel(p.first, p.second);
    draw_marker(canvas, x, y, index, series.rgb);
  }
}

/// The legend box in the top right corner of the plotting area: a sample of each line and its name.
void draw_legend(Canvas& canvas, const PlotAxes& axes, const LogLogPlot& plot) {
  struct Entry {
    const std::string* name;
    PlotColor rgb;
    bool dashed;
    std::optional<size_t> marker;
  };
  std::vector<Entry> entries;
  for (size_t i = 0; i < plot.series.size(); ++i) {
    const PlotSeries& s = plot.series[i];
    if (s.name.empty()) continue;
    entries.push_back({&s.name, s.rgb, s.dashed, s.markers ? std::optional(i) : std::nullopt});
  }
  if (plot.slope_line && !plot.slope_line->name.empty()) {
    entries.push_back({&plot.slope_line->name, plot.slope_line->rgb, true, std::nullopt});
  }
  if (entries.empty()) return;

  int name_width = 0;
  for (const Entry& e : entries) name_width = std::max(name_width, text_width(*e.name, 1));
  const int width = 8 + kLegendSample + 8 + name_width + 8;
  const int height = int(entries.size()) * kLegendRow + 8;
  const int x0 = std::max(axes.left + 1, axes.right - 8 - width);
  const int y0 = axes.top + 8;
  canvas.fill(x0, y0, x0 + width, y0 + height, kBackground);
  canvas.outline(x0, y0, x0 + width, y0 + height, kFrame);
  for (size_t i = 0; i < entries.size(); ++i) {
    const Entry& e = entries[i];
    const int yc = y0 + 4 + int(i) * kLegendRow + kLegendRow / 2;
    Pen pen{e.rgb, e.dashed};
    draw_line(canvas, x0 + 8, yc - 1, x0 + 8 + kLegendSample, yc - 1, pen);
    if (e.marker) draw_marker(canvas, x0 + 8 + kLegendSample / 2, yc - 0.5, *e.marker, e.rgb);
    draw_text(canvas, x0 + 8 + kLegendSample + 8, yc - kGlyphHeight / 2, *e.name, kInk);
  }
}

void draw_labels(Canvas& canvas, const PlotAxes& axes, const LogLogPlot& plot, int width) {
  const int x_mid = (axes.left + axes.right) / 2;
  draw_text(canvas, x_mid - text_width(plot.x_label, 1) / 2, axes.bottom + 24, plot.x_label, kInk);
  const int y_mid = (axes.top + axes.bottom) / 2;
  draw_text(canvas, 10, y_mid + text_width(plot.y_label, 1) / 2, plot.y_label, kInk, 1, true);
  // The title at twice the size when it fits, else at the normal size.
  const int scale = text_width(plot.title, 2) <= width - 8 ? 2 : 1;
  draw_text(canvas, (width - text_width(plot.title, scale)) / 2, (axes.top - 7 * scale) / 2,
            plot.title, kInk, scale);
}

}  // namespace

std::pair<double, double> PlotAxes::to_pixel(double x, double y) const {
  const double fx = (std::log10(x) - std::log10(x_min)) / (std::log10(x_max) - std::log10(x_min));
  const double fy = (std::log10(y) - std::log10(y_min)) / (std::log10(y_max) - std::log10(y_min));
  return {left + fx * (right - left), bottom - fy * (bottom - top)};
}

PlotAxes plot_axes(const LogLogPlot& plot, int width, int height) {
  std::tie(width, height) = width_height(width, height);
  PlotAxes axes;
  axes.left = kMarginLeft;
  axes.top = kMarginTop;
  axes.right = width - 1 - kMarginRight;
  axes.bottom = height - 1 - kMarginBottom;

  bool any = false;
  double x_lo = 0, x_hi = 0, y_lo = 0, y_hi = 0;  // log10 of the data's extremes
  for (const PlotSeries& s : plot.series) {
    for (const PlotPoint& p : s.points) {
      if (!drawable(p)) continue;
      const double lx = std::log10(p.first), ly = std::log10(p.second);
      x_lo = any ? std::min(x_lo, lx) : lx;
      x_hi = any ? std::max(x_hi, lx) : lx;
      y_lo = any ? std::min(y_lo, ly) : ly;
      y_hi = any ? std::max(y_hi, ly) : ly;
      any = true;
    }
  }
  const auto [xd_lo, xd_hi] = decade_range(x_lo, x_hi);
  const auto [yd_lo, yd_hi] = decade_range(y_lo, y_hi);
  axes.x_min = std::pow(10.0, xd_lo);
  axes.x_max = std::pow(10.0, xd_hi);
  axes.y_min = std::pow(10.0, yd_lo);
  axes.y_max = std::pow(10.0, yd_hi);
  return axes;
}

PlotImage render_plot(const LogLogPlot& plot, int width, int height) {
  std::tie(width, height) = width_height(width, height);
  const PlotAxes axes = plot_axes(plot, width, height);
  Canvas canvas(width, height);
  draw_grid_and_ticks(canvas, axes);
  canvas.outline(axes.left, axes.top, axes.right, axes.bottom, kFrame);
  if (plot.slope_line) draw_slope_line(canvas, axes, *plot.slope_line);
  for (size_t i = 0; i < plot.series.size(); ++i) draw_series(canvas, axes, plot.series[i], i);
  draw_legend(canvas, axes, plot);
  draw_labels(canvas, axes, plot, width);
  return canvas.take();
}

void write_plot_png(const LogLogPlot& plot, const std::filesystem::path& path, int width,
                    int height) {
  const PlotImage image = render_plot(plot, width, height);
  write_png_rgb8(path, image.rgb, uint32_t(image.width), uint32_t(image.height));
}

std::optional<double> loglog_slope(const std::vector<PlotPoint>& points) {
  std::vector<std::pair<double, double>> logs;
  for (const PlotPoint& p : points) {
    if (drawable(p)) logs.emplace_back(std::log10(p.first), std::log10(p.second));
  }
  if (logs.size() < 2) return std::nullopt;
  double mx = 0, my = 0;
  for (const auto& [lx, ly] : logs) {
    mx += lx;
    my += ly;
  }
  mx /= double(logs.size());
  my /= double(logs.size());
  double sxx = 0, sxy = 0;
  for (const auto& [lx, ly] : logs) {
    sxx += (lx - mx) * (lx - mx);
    sxy += (lx - mx) * (ly - my);
  }
  if (!(sxx > 0)) return std::nullopt;  // every x the same
  return sxy / sxx;
}

}  // namespace rayfarm
