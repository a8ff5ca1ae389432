// Log-log plots: axes in whole decades, series drawn where their data lie, gaps for points
// without a logarithm, dashes, the slope line, text, PNG output, and the log-log slope fit.
#include "common/report/plot.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/read_png.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

constexpr PlotColor kRed{200, 30, 30};
constexpr PlotColor kGreen{20, 160, 40};
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

PlotColor pixel(const PlotImage& image, int x, int y) {
  const size_t i = (size_t(y) * size_t(image.width) + size_t(x)) * 3;
  return {image.rgb[i], image.rgb[i + 1], image.rgb[i + 2]};
}

/// Whether a pixel of colour `c` lies within `radius` pixels (a square) of (x, y).
bool colour_near(const PlotImage& image, double fx, double fy, int radius, const PlotColor& c) {
  const int cx = int(std::lround(fx)), cy = int(std::lround(fy));
  for (int y = cy - radius; y <= cy + radius; ++y) {
    for (int x = cx - radius; x <= cx + radius; ++x) {
      if (x < 0 || y < 0 || x >= image.width || y >= image.height) continue;
      if (pixel(image, x, y) == c) return true;
    }
  }
  return false;
}

int count_colour(const PlotImage& image, const PlotColor& c) {
  int n = 0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) n += pixel(image, x, y) == c;
  }
  return n;
}

LogLogPlot one_line(std::vector<PlotPoint> points, bool markers = false) {
  LogLogPlot plot;
  PlotSeries s{"", kRed, std::move(points)};
  s.markers = markers;
  plot.series.push_back(std::move(s));
  return plot;
}

TEST(PlotAxes, SpanWholeDecadesThatCoverTheData) {
  const LogLogPlot plot = one_line({{0.3, 0.5}, {20.0, 2e-3}});
  const PlotAxes axes = plot_axes(plot, 800, 600);
  EXPECT_DOUBLE_EQ(axes.x_min, 0.1);
  EXPECT_DOUBLE_EQ(axes.x_max, 100.0);
  EXPECT_DOUBLE_EQ(axes.y_min, 1e-3);
  EXPECT_DOUBLE_EQ(axes.y_max, 1.0);
  // The plotting area lies inside the image, with room for labels around it.
  EXPECT_GT(axes.left, 0);
  EXPECT_GT(axes.top, 0);
  EXPECT_LT(axes.right, 799);
  EXPECT_LT(axes.bottom, 599);
  EXPECT_LT(axes.left, axes.right);
  EXPECT_LT(axes.top, axes.bottom);
  // Corners of the data range land on the corners of the area; y grows upwards.
  const auto [x0, y0] = axes.to_pixel(0.1, 1e-3);
  EXPECT_NEAR(x0, axes.left, 1e-9);
  EXPECT_NEAR(y0, axes.bottom, 1e-9);
  const auto [x1, y1] = axes.to_pixel(100.0, 1.0);
  EXPECT_NEAR(x1, axes.right, 1e-9);
  EXPECT_NEAR(y1, axes.top, 1e-9);
}

TEST(PlotAxes, ValuesOnADecadeDoNotAddAnother) {
  const PlotAxes axes = plot_axes(one_line({{1.0, 1e-3}, {10.0, 1e-1}}), 800, 600);
  EXPECT_DOUBLE_EQ(axes.x_min, 1.0);
  EXPECT_DOUBLE_EQ(axes.x_max, 10.0);
  EXPECT_DOUBLE_EQ(axes.y_min, 1e-3);
  EXPECT_DOUBLE_EQ(axes.y_max, 1e-1);
}

TEST(PlotAxes, OnePointStillGetsADecade) {
  const PlotAxes axes = plot_axes(one_line({{5.0, 0.02}}), 800, 600);
  EXPECT_DOUBLE_EQ(axes.x_min, 1.0);
  EXPECT_DOUBLE_EQ(axes.x_max, 10.0);
  EXPECT_DOUBLE_EQ(axes.y_min, 1e-2);
  EXPECT_DOUBLE_EQ(axes.y_max, 1e-1);
}

TEST(PlotAxes, PointsWithoutALogarithmAreLeftOut) {
  const LogLogPlot plot = one_line({{1.5, 1e-2},
                                    {0.0, 1e-3},
                                    {-1.0, 5.0},
                                    {2.0, 0.0},
                                    {3.0, -2.0},
                                    {kNan, 1.0},
                                    {4.0, kInf},
                                    {5.0, 2e-3}});
  const PlotAxes axes = plot_axes(plot, 800, 600);
  EXPECT_DOUBLE_EQ(axes.x_min, 1.0);
  EXPECT_DOUBLE_EQ(axes.x_max, 10.0);
  EXPECT_DOUBLE_EQ(axes.y_min, 1e-3);
  EXPECT_DOUBLE_EQ(axes.y_max, 1e-2);
}

TEST(RenderPlot, DrawsASeriesAlongItsLine) {
  const LogLogPlot plot = one_line({{1.0, 1e-1}, {100.0, 1e-3}});
  const PlotImage image = render_plot(plot, 800, 600);
  ASSERT_EQ(image.width, 800);
  ASSERT_EQ(image.height, 600);
  ASSERT_EQ(image.rgb.size(), 800u * 600u * 3u);
  const PlotAxes axes = plot_axes(plot, 800, 600);
  const auto [x0, y0] = axes.to_pixel(1.0, 1e-1);
  const auto [x1, y1] = axes.to_pixel(100.0, 1e-3);
  // On a log-log plot the line between two points passes through their geometric mean too.
  const auto [xm, ym] = axes.to_pixel(10.0, 1e-2);
  EXPECT_TRUE(colour_near(image, xm, ym, 1, kRed));
  for (double t : {0.1, 0.25, 0.5, 0.75, 0.9}) {
    SCOPED_TRACE(t);
    EXPECT_TRUE(colour_near(image, x0 + t * (x1 - x0), y0 + t * (y1 - y0), 1, kRed));
  }
  // Far from the line (the other diagonal's ends) there is none of its colour.
  EXPECT_FALSE(colour_near(image, x0, y1, 5, kRed));
  EXPECT_FALSE(colour_near(image, x1, y0, 5, kRed));
  // The line is continuous: every column between its ends has a pixel of its colour.
  for (int x = int(std::ceil(x0)); x <= int(std::floor(x1)); ++x) {
    bool found = false;
    for (int y = 0; y < image.height && !found; ++y) found = pixel(image, x, y) == kRed;
    ASSERT_TRUE(found) << "column " << x;
  }
}

TEST(RenderPlot, MarkersSitOnThePoints) {
  const LogLogPlot plot = one_line({{2.0, 3e-2}, {7.0, 4e-3}}, /*markers=*/true);
  const PlotImage image = render_plot(plot);
  const PlotAxes axes = plot_axes(plot, 800, 600);
  for (const auto& [x, y] : plot.series[0].points) {
    const auto [px, py] = axes.to_pixel(x, y);
    // A marker is a filled blob: the point and its 4 neighbours two pixels away are coloured.
    EXPECT_TRUE(colour_near(image, px, py, 0, kRed));
    EXPECT_TRUE(colour_near(image, px + 2, py, 0, kRed));
    EXPECT_TRUE(colour_near(image, px - 2, py, 0, kRed));
    EXPECT_TRUE(colour_near(image, px, py + 2, 0, kRed));
    EXPECT_TRUE(colour_near(image, px, py - 2, 0, kRed));
  }
}

TEST(RenderPlot, APointWithoutALogarithmBreaksTheLine) {
  const LogLogPlot plot = one_line({{1.0, 1e-1}, {3.0, 0.0}, {100.0, 1e-3}});
  const PlotImage image = render_plot(plot);
  const PlotAxes axes = plot_axes(plot, 800, 600);
  const auto [xm, ym] = axes.to_pixel(10.0, 1e-2);
  EXPECT_FALSE(colour_near(image, xm, ym, 3, kRed));
  EXPECT_EQ(count_colour(image, kRed), 0) << "no segment and no markers: nothing drawn";
}

TEST(RenderPlot, DashedLinesHaveGaps) {
  LogLogPlot plot = one_line({{1.0, 1e-2}, {100.0, 1e-2}});
  plot.series[0].dashed = true;
  const PlotImage image = render_plot(plot);
  const PlotAxes axes = plot_axes(plot, 800, 600);
  const auto [x0, y] = axes.to_pixel(1.0, 1e-2);
  const auto [x1, y_] = axes.to_pixel(100.0, 1e-2);
  int on = 0, off = 0;
  for (int x = int(x0) + 1; x < int(x1); ++x) {
    (colour_near(image, x, y, 0, kRed) || colour_near(image, x, y + 1, 0, kRed)) ? ++on : ++off;
  }
  EXPECT_GT(on, (on + off) / 3);
  EXPECT_GT(off, (on + off) / 5);
}

TEST(RenderPlot, SlopeLinePassesThroughItsPointWithItsSlope) {
  LogLogPlot plot = one_line({{0.5, 1e-1}, {50.0, 1e-3}});
  plot.slope_line = SlopeLine{"1/t", {2.0, 4e-2}, -1.0, kGreen};
  const PlotImage image = render_plot(plot);
  const PlotAxes axes = plot_axes(plot, 800, 600);
  // Sample the line y = 4e-2 * (x / 2)^-1 across the plot; dashed, so most samples (not all) are
  // on a dash; the series's line (slope -1 through other points) is elsewhere.
  int on = 0, samples = 0;
  for (double x = 0.2; x <= 90.0; x *= 1.07) {
    const auto [px, py] = axes.to_pixel(x, 4e-2 * 2.0 / x);
    ++samples;
    on += colour_near(image, px, py, 1, kGreen);
  }
  EXPECT_GT(on, samples / 2);
  EXPECT_LT(on, samples);
  // Nothing of its colour off the line, e.g. at the same x a decade away.
  const auto [px, py] = axes.to_pixel(2.0, 4e-3);
  EXPECT_FALSE(colour_near(image, px, py, 3, kGreen));
  // It stays inside the plotting area.
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (pixel(image, x, y) != kGreen) continue;
      ASSERT_TRUE(x >= axes.left && x <= axes.right && y >= axes.top && y <= axes.bottom)
          << x << "," << y;
    }
  }
}

TEST(RenderPlot, EmptyAndDegenerateDataDrawWithoutFailing) {
  std::vector<LogLogPlot> plots(6);
  plots[1].series.push_back({"empty", kRed, {}});
  plots[2] = one_line({{0.0, 0.0}, {-1.0, -1.0}, {kNan, kNan}, {kInf, 1.0}});
  plots[3] = one_line({{1e-320, 1e300}, {1e305, 1e-305}, {std::numeric_limits<double>::min(), 1}});
  plots[4] = one_line({{1.0, 1.0}, {1.0, 1.0}, {1.0, 1.0}});
  plots[5].slope_line = SlopeLine{"1/t", {0.0, kNan}, kInf};
  for (size_t i = 0; i < plots.size(); ++i) {
    SCOPED_TRACE(i);
    const PlotImage image = render_plot(plots[i], 300, 200);
    EXPECT_EQ(image.width, 300);
    EXPECT_EQ(image.height, 200);
    EXPECT_EQ(image.rgb.size(), 300u * 200u * 3u);
  }
  const PlotAxes axes = plot_axes(LogLogPlot{}, 800, 600);
  EXPECT_DOUBLE_EQ(axes.x_min, 1.0);
  EXPECT_DOUBLE_EQ(axes.x_max, 10.0);
  EXPECT_DOUBLE_EQ(axes.y_min, 1.0);
  EXPECT_DOUBLE_EQ(axes.y_max, 10.0);
}

TEST(RenderPlot, TinySizesAreRaised) {
  const PlotImage image = render_plot(one_line({{1.0, 1.0}, {2.0, 0.5}}), 10, -5);
  EXPECT_GE(image.width, 200);
  EXPECT_GE(image.height, 150);
  EXPECT_EQ(image.rgb.size(), size_t(image.width) * size_t(image.height) * 3);
}

TEST(RenderPlot, TextIsDrawn) {
  LogLogPlot plain = one_line({{1.0, 1e-1}, {10.0, 1e-2}});
  LogLogPlot titled = plain;
  titled.title = "Cornell box: relMSE";
  titled.x_label = "time (s)";
  const PlotImage a = render_plot(plain);
  const PlotImage b = render_plot(titled);
  const PlotAxes axes = plot_axes(plain, 800, 600);
  // The title lies in the band above the plotting area; dark pixels appear there only with it.
  const auto dark_in_rows = [](const PlotImage& image, int y0, int y1) {
    int n = 0;
    for (int y = y0; y < y1; ++y) {
      for (int x = 0; x < image.width; ++x) n += pixel(image, x, y)[0] < 100;
    }
    return n;
  };
  // (The top decade label reaches a few rows above the area.)
  EXPECT_EQ(dark_in_rows(a, 0, axes.top - 6), 0);
  EXPECT_GT(dark_in_rows(b, 0, axes.top - 6), 50);
  // The x label lies below the tick labels.
  EXPECT_GT(dark_in_rows(b, axes.bottom + 20, b.height),
            dark_in_rows(a, axes.bottom + 20, a.height));
  // Decade labels are drawn left of the plotting area in both.
  int left_ink = 0;
  for (int y = axes.top; y <= axes.bottom; ++y) {
    for (int x = 0; x < axes.left - 2; ++x) left_ink += pixel(a, x, y)[0] < 100;
  }
  EXPECT_GT(left_ink, 20);
}

TEST(RenderPlot, IsDeterministic) {
  LogLogPlot plot;
  plot.title = "three curves";
  plot.series.push_back({"naive", kRed, {{0.5, 1e-1}, {1.0, 5e-2}, {2.0, 2.5e-2}}});
  plot.series.push_back({"nee", kGreen, {{0.5, 3e-2}, {1.0, 1.5e-2}}, true});
  plot.series.push_back({"mis", {40, 90, 200}, {{0.5, 2e-2}, {1.0, 1e-2}, {4.0, 2.5e-3}}});
  plot.slope_line = SlopeLine{"1/t", {0.5, 1e-1}};
  EXPECT_EQ(render_plot(plot).rgb, render_plot(plot).rgb);
}

TEST(WritePlotPng, WritesThePlotAsAPng) {
  testing::TempDir dir;
  const LogLogPlot plot = one_line({{1.0, 1e-1}, {100.0, 1e-3}}, true);
  const auto path = dir.path() / "plot.png";
  write_plot_png(plot, path, 640, 480);
  const testing::RgbImage read = testing::read_png_rgb8(path);
  ASSERT_TRUE(read.error.empty()) << read.error;
  EXPECT_EQ(read.width, 640u);
  EXPECT_EQ(read.height, 480u);
  EXPECT_EQ(read.rgb, render_plot(plot, 640, 480).rgb);
  // No temporary file left beside it.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()),
                          std::filesystem::directory_iterator()),
            1);
}

TEST(WritePlotPng, NamesThePathWhenItCannotWrite) {
  testing::TempDir dir;
  const auto path = dir.path() / "missing-folder" / "plot.png";
  try {
    write_plot_png(one_line({{1.0, 1.0}}), path);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

TEST(LogLogSlope, FitsAPowerLaw) {
  std::vector<PlotPoint> inverse, root;
  for (double t = 0.5; t < 100; t *= 1.5) {
    inverse.emplace_back(t, 0.3 / t);
    root.emplace_back(t, 2.0 / std::sqrt(t));
  }
  ASSERT_TRUE(loglog_slope(inverse));
  EXPECT_NEAR(*loglog_slope(inverse), -1.0, 1e-12);
  EXPECT_NEAR(*loglog_slope(root), -0.5, 1e-12);
  // Least squares: y = x^-1 times factors 2 and 1/2 alternating still fits about -1.
  std::vector<PlotPoint> noisy;
  for (int i = 0; i < 20; ++i) {
    const double t = std::pow(10.0, i / 5.0);
    noisy.emplace_back(t, (i % 2 ? 2.0 : 0.5) / t);
  }
  EXPECT_NEAR(*loglog_slope(noisy), -1.0, 0.1);
}

TEST(LogLogSlope, SkipsPointsWithoutALogarithmAndNeedsTwoDistinctX) {
  EXPECT_NEAR(*loglog_slope({{1.0, 1.0}, {0.0, 5.0}, {10.0, -1.0}, {10.0, 0.01}, {kNan, 1.0}}),
              -2.0, 1e-12);
  EXPECT_FALSE(loglog_slope({}));
  EXPECT_FALSE(loglog_slope({{1.0, 1.0}}));
  EXPECT_FALSE(loglog_slope({{2.0, 1.0}, {2.0, 0.5}}));
  EXPECT_FALSE(loglog_slope({{1.0, 0.0}, {2.0, 0.0}}));
}

}  // namespace
}  // namespace rayfarm
