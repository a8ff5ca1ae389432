#pragma once
// Log-log line plots written as PNG: the error-against-time figure of a render (error.png) and
// benchmark comparisons (several integrators on one plot). Deterministic: the same plot gives the
// same bytes. Text is drawn with a built-in 5x7 bitmap font (ASCII 32..126).
//
// Usage:
//   LogLogPlot plot;
//   plot.title = "Cornell box";  plot.x_label = "time (s)";  plot.y_label = "relMSE";
//   plot.series.push_back({"naive", {200, 40, 40}, {{0.5, 1e-1}, {1.0, 5e-2}, {2.0, 2.5e-2}}});
//   plot.series.push_back({"mis", {40, 90, 200}, {{0.5, 2e-2}, {1.0, 1e-2}}});
//   plot.slope_line = SlopeLine{"1/t", {0.5, 1e-1}};
//   write_plot_png(plot, "convergence.png");
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace rayfarm {

/// A data point (x, y). Only points with x and y in [1e-300, 1e300] have a place on log-log axes
/// ("drawable"); the others (zero, negative, NaN, infinite) are skipped and break their line.
using PlotPoint = std::pair<double, double>;

/// An 8-bit sRGB colour.
using PlotColor = std::array<uint8_t, 3>;

/// One named curve: its points joined in order by straight lines, with a marker at each point.
struct PlotSeries {
  std::string name;        ///< legend text ("" = not in the legend)
  PlotColor rgb{0, 0, 0};  ///< line and marker colour
  std::vector<PlotPoint> points;
  bool dashed = false;  ///< dashed instead of solid line
  bool markers = true;  ///< a filled marker at each point: square, diamond, triangle, circle
                        ///< for the 1st, 2nd, 3rd, 4th series (then again)
};

/// A reference line y = through.y * (x / through.x)^slope (a straight line on log-log axes),
/// drawn dashed across the whole plotting area; slope -1 is the 1/t convergence of Monte Carlo.
struct SlopeLine {
  std::string name = "1/t";     ///< legend text
  PlotPoint through{1.0, 1.0};  ///< a point it passes through (both > 0)
  double slope = -1.0;
  PlotColor rgb{140, 140, 140};
};

/// A whole figure. The axes span whole decades that cover every drawable point of every series
/// (the slope line does not widen them); decades are marked by grid lines labelled 1e-3, 1e-2, ...
struct LogLogPlot {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<PlotSeries> series;
  std::optional<SlopeLine> slope_line;
};

/// An 8-bit RGB image, row-major, top row first.
struct PlotImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgb;  ///< width * height * 3 bytes
};

/// Where a plot drawn at a given size puts its data: the data range of the axes (powers of ten)
/// and the pixel rectangle of the plotting area.
struct PlotAxes {
  double x_min = 1, x_max = 10, y_min = 1, y_max = 10;  ///< data range shown
  int left = 0, top = 0, right = 0, bottom = 0;         ///< plotting area, pixels (inclusive)
  /// The pixel position (column, row; fractional) of data point (x, y), both > 0.
  std::pair<double, double> to_pixel(double x, double y) const;
};

/// The axes that render_plot uses for `plot` at width x height pixels. With no drawable point,
/// both axes span 1..10.
PlotAxes plot_axes(const LogLogPlot& plot, int width, int height);

/// Draws `plot` into an image of width x height pixels (each clamped to 200..8192 wide and
/// 150..8192 high). Never throws for any data.
PlotImage render_plot(const LogLogPlot& plot, int width = 800, int height = 600);

/// Draws `plot` and writes it as a PNG file, atomically. Throws std::runtime_error
/// ("cannot write PATH: cause") when the file cannot be written.
void write_plot_png(const LogLogPlot& plot, const std::filesystem::path& path, int width = 800,
                    int height = 600);

/// The least-squares slope of log10(y) against log10(x) over the drawable points; no value when
/// fewer than two of them have distinct x. About -1 for a Monte Carlo error against time.
std::optional<double> loglog_slope(const std::vector<PlotPoint>& points);

}  // namespace rayfarm
