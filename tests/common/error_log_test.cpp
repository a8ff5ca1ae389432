// error.csv: the documented columns, bit-exact round trips, errors naming file:line, the terminal
// table, and the error plot.
#include "common/report/error_log.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/read_png.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

/// The header's column list, as documented in error_log.h.
constexpr const char* kDocumentedHeader =
    "time_s,spp,samples_per_s,est_rel_mse,est_rmse,ref_rel_mse,ref_rmse,ref_mae,ref_max";

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> cells_of(const std::string& line) {
  std::vector<std::string> cells;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    cells.push_back(line.substr(start, comma - start));
    if (comma == std::string::npos) return cells;
    start = comma + 1;
  }
}

uint64_t bits(double v) { return std::bit_cast<uint64_t>(v); }

void expect_same_bits(const std::optional<double>& a, const std::optional<double>& b,
                      const char* what) {
  ASSERT_EQ(a.has_value(), b.has_value()) << what;
  if (a) {
    EXPECT_EQ(bits(*a), bits(*b)) << what << ": " << *a << " vs " << *b;
  }
}

void expect_same_rows(const std::vector<ErrorRow>& a, const std::vector<ErrorRow>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE("row " + std::to_string(i));
    expect_same_bits(a[i].time_s, b[i].time_s, "time_s");
    expect_same_bits(a[i].spp, b[i].spp, "spp");
    expect_same_bits(a[i].samples_per_s, b[i].samples_per_s, "samples_per_s");
    expect_same_bits(a[i].est_rel_mse, b[i].est_rel_mse, "est_rel_mse");
    expect_same_bits(a[i].est_rmse, b[i].est_rmse, "est_rmse");
    expect_same_bits(a[i].ref_rel_mse, b[i].ref_rel_mse, "ref_rel_mse");
    expect_same_bits(a[i].ref_rmse, b[i].ref_rmse, "ref_rmse");
    expect_same_bits(a[i].ref_mae, b[i].ref_mae, "ref_mae");
    expect_same_bits(a[i].ref_max, b[i].ref_max, "ref_max");
  }
}

/// Rows whose numbers have no short decimal form, with every pattern of missing optionals.
std::vector<ErrorRow> awkward_rows() {
  std::vector<ErrorRow> rows;
  ErrorRow a;
  a.time_s = 0.1 + 0.2;
  a.spp = 1.0 / 3.0;
  a.samples_per_s = 123456789.123456789;
  a.est_rel_mse = std::nextafter(1e-3, 1.0);
  a.est_rmse = std::numeric_limits<double>::denorm_min();
  rows.push_back(a);
  ErrorRow b = a;
  b.time_s = 2.0 / 3.0;
  b.spp = 16;
  b.est_rel_mse = 0.0;
  b.est_rmse = std::numeric_limits<double>::max();
  b.ref_rel_mse = std::numeric_limits<double>::min();
  b.ref_rmse = 1e-300;
  b.ref_mae = 0.7;
  b.ref_max = 123.456e7;
  rows.push_back(b);
  ErrorRow c = a;
  c.time_s = 1e5 + 1.0 / 7.0;
  c.ref_rmse = -0.0;  // only some references
  c.ref_max = 5e-324;
  rows.push_back(c);
  return rows;
}

TEST(ErrorCsv, HeaderIsTheDocumentedColumns) {
  const std::vector<std::string> lines = lines_of(format_error_csv({}));
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0], kDocumentedHeader);
  EXPECT_TRUE(parse_error_csv(format_error_csv({}), "empty.csv").empty());
}

TEST(ErrorCsv, MissingOptionalsAreEmptyCells) {
  ErrorRow row;
  row.time_s = 1.5;
  row.spp = 4;
  row.samples_per_s = 1000;
  row.est_rel_mse = 0.25;
  row.est_rmse = 0.5;
  row.ref_rmse = 0.125;
  const std::vector<std::string> lines = lines_of(format_error_csv({row}));
  ASSERT_EQ(lines.size(), 2u);
  const std::vector<std::string> cells = cells_of(lines[1]);
  ASSERT_EQ(cells.size(), 9u);
  EXPECT_EQ(std::stod(cells[0]), 1.5);
  EXPECT_EQ(std::stod(cells[3]), 0.25);
  EXPECT_EQ(cells[5], "");
  EXPECT_EQ(std::stod(cells[6]), 0.125);
  EXPECT_EQ(cells[7], "");
  EXPECT_EQ(cells[8], "");
}

TEST(ErrorCsv, RoundTripIsBitExact) {
  const std::vector<ErrorRow> rows = awkward_rows();
  expect_same_rows(parse_error_csv(format_error_csv(rows), "mem.csv"), rows);

  testing::TempDir dir;
  const fs::path path = dir.path() / "error.csv";
  write_error_csv(path, rows);
  expect_same_rows(read_error_csv(path), rows);
  // Written again over the old file, atomically: no temporary left beside it.
  write_error_csv(path, {rows[0]});
  expect_same_rows(read_error_csv(path), {rows[0]});
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(ErrorCsv, ReadsCrlfBlankLinesAndSpaces) {
  const std::string text = std::string(kDocumentedHeader) + "\r\n" +
                           " 1.5, 8 ,100,0.5,0.25,,,,\r\n"
                           "\r\n"
                           "3,16,200,0.125,0.0625,0.1,,,2\r\n\n";
  const std::vector<ErrorRow> rows = parse_error_csv(text, "crlf.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].time_s, 1.5);
  EXPECT_EQ(rows[0].spp, 8.0);
  EXPECT_FALSE(rows[0].ref_rel_mse);
  EXPECT_EQ(rows[1].est_rmse, 0.0625);
  EXPECT_EQ(rows[1].ref_rel_mse, 0.1);
  EXPECT_FALSE(rows[1].ref_mae);
  EXPECT_EQ(rows[1].ref_max, 2.0);
}

/// Parsing `text` as "bad.csv" throws ErrorLogError whose message starts with "bad.csv:LINE:"
/// and contains `also`.
void expect_error_at(const std::string& text, int line, const std::string& also = "") {
  SCOPED_TRACE(text);
  try {
    parse_error_csv(text, "bad.csv");
    FAIL() << "expected ErrorLogError";
  } catch (const ErrorLogError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("bad.csv:" + std::to_string(line) + ":", 0), 0u) << what;
    EXPECT_NE(what.find(also), std::string::npos) << what;
  }
}

TEST(ErrorCsv, MalformedInputNamesFileAndLine) {
  const std::string h = std::string(kDocumentedHeader) + "\n";
  const std::string good = "1,2,3,4,5,,,,\n";
  expect_error_at(h + good + "1,2,3,4,5,,,\n", 3, "8");            // a cell short
  expect_error_at(h + good + good + "1,2,3,4,5,,,,,\n", 4, "10");  // a cell too many
  expect_error_at(h + "1,2,abc,4,5,,,,\n", 2, "abc");              // not a number
  expect_error_at(h + good + "1,2,3,4,5,0.5x,,,\n", 3, "0.5x");    // trailing junk
  expect_error_at(h + "1,2,3,4,5,,,,0x\n", 2, "ref_max");          // names the column
  expect_error_at(h + "1,,3,4,5,,,,\n", 2, "spp");                 // required cell empty
  expect_error_at(good + good, 1, "header");                       // no header
  expect_error_at("time_s,spp\n" + good, 1, "header");             // wrong header
  expect_error_at("", 1, "header");                                // empty file
  expect_error_at("\n\n", 1, "header");                            // blank file
  expect_error_at(h + "\n\n" + "1;2;3;4;5;;;;\n", 4);              // blank lines still count
}

TEST(ErrorCsv, ReadingAMissingFileNamesIt) {
  testing::TempDir dir;
  const fs::path path = dir.path() / "nope" / "error.csv";
  try {
    read_error_csv(path);
    FAIL() << "expected ErrorLogError";
  } catch (const ErrorLogError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
  // A malformed file on disk is reported with its path and line.
  const fs::path bad = dir.write("bad/error.csv", std::string(kDocumentedHeader) + "\n1,2\n");
  try {
    read_error_csv(bad);
    FAIL() << "expected ErrorLogError";
  } catch (const ErrorLogError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(bad.string() + ":2:", 0), 0u) << e.what();
  }
}

/// Rows of a render without a reference: error halves as time doubles.
std::vector<ErrorRow> converging_rows(int n, bool reference) {
  std::vector<ErrorRow> rows;
  for (int i = 0; i < n; ++i) {
    ErrorRow r;
    r.time_s = 0.5 * std::pow(2.0, i);
    r.spp = 4.0 * std::pow(2.0, i);
    r.samples_per_s = 2.5e6 + i;
    r.est_rel_mse = 0.08 / std::pow(2.0, i);
    r.est_rmse = std::sqrt(r.est_rel_mse) / 10;
    if (reference && i > 0) {  // the first row without, to show a missing cell
      r.ref_rel_mse = 1.1 * r.est_rel_mse;
      r.ref_rmse = 1.05 * r.est_rmse;
      r.ref_mae = 0.5 * r.est_rmse;
      r.ref_max = 3.0;
    }
    rows.push_back(r);
  }
  return rows;
}

std::vector<std::string> words_of(const std::string& line) {
  std::vector<std::string> words;
  std::istringstream in(line);
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

TEST(ErrorTable, AlignedColumnsWithTheValues) {
  const std::vector<ErrorRow> rows = converging_rows(5, false);
  const std::vector<std::string> lines = lines_of(format_error_table(rows));
  ASSERT_EQ(lines.size(), rows.size() + 1);
  for (const std::string& line : lines) EXPECT_EQ(line.size(), lines[0].size()) << line;
  EXPECT_NE(lines[0].find("spp"), std::string::npos);
  EXPECT_NE(lines[0].find("relMSE"), std::string::npos);
  EXPECT_EQ(lines[0].find("ref"), std::string::npos) << "no reference columns without a reference";
  for (size_t i = 0; i < rows.size(); ++i) {
    const std::vector<std::string> w = words_of(lines[i + 1]);
    ASSERT_EQ(w.size(), 5u) << lines[i + 1];
    EXPECT_NEAR(std::stod(w[0]), rows[i].time_s, 1e-3);
    EXPECT_NEAR(std::stod(w[1]), rows[i].spp, 1e-2);
    EXPECT_NEAR(std::stod(w[2]) / rows[i].samples_per_s, 1.0, 1e-3);
    EXPECT_NEAR(std::stod(w[3]) / rows[i].est_rel_mse, 1.0, 1e-3);
    EXPECT_NEAR(std::stod(w[4]) / rows[i].est_rmse, 1.0, 1e-3);
  }
}

TEST(ErrorTable, ReferenceColumnsWhenAnyRowHasThem) {
  const std::vector<ErrorRow> rows = converging_rows(4, true);
  const std::vector<std::string> lines = lines_of(format_error_table(rows));
  ASSERT_EQ(lines.size(), rows.size() + 1);
  EXPECT_NE(lines[0].find("ref"), std::string::npos);
  for (const std::string& line : lines) EXPECT_EQ(line.size(), lines[0].size()) << line;
  // The first row has no reference figures: four placeholders, no numbers, in their place.
  std::vector<std::string> w = words_of(lines[1]);
  ASSERT_EQ(w.size(), 9u) << lines[1];
  for (size_t i = 5; i < 9; ++i) EXPECT_THROW(std::stod(w[i]), std::invalid_argument) << w[i];
  w = words_of(lines[2]);
  ASSERT_EQ(w.size(), 9u) << lines[2];
  EXPECT_NEAR(std::stod(w[5]) / *rows[1].ref_rel_mse, 1.0, 1e-3);
  EXPECT_NEAR(std::stod(w[8]), 3.0, 1e-3);
}

TEST(ErrorTable, NoRowsIsJustTheHeader) { EXPECT_EQ(lines_of(format_error_table({})).size(), 1u); }

/// Distinct strongly coloured (not grey) pixel values in an image.
std::set<uint32_t> saturated_colours(const testing::RgbImage& image) {
  std::set<uint32_t> colours;
  for (size_t i = 0; i + 2 < image.rgb.size(); i += 3) {
    const int r = image.rgb[i], g = image.rgb[i + 1], b = image.rgb[i + 2];
    if (std::max({r, g, b}) - std::min({r, g, b}) > 60)
      colours.insert(uint32_t(r << 16 | g << 8 | b));
  }
  return colours;
}

TEST(ErrorPlot, DrawsEstimatedAndMeasuredCurves) {
  testing::TempDir dir;
  const fs::path without = dir.path() / "estimated.png";
  const fs::path with = dir.path() / "measured.png";
  write_error_plot(without, converging_rows(6, false), "no reference");
  write_error_plot(with, converging_rows(6, true), "with a reference");
  const testing::RgbImage a = testing::read_png_rgb8(without);
  const testing::RgbImage b = testing::read_png_rgb8(with);
  ASSERT_TRUE(a.error.empty()) << a.error;
  ASSERT_TRUE(b.error.empty()) << b.error;
  EXPECT_GT(a.width, 0u);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  // One coloured curve without a reference, a second colour with it.
  EXPECT_EQ(saturated_colours(a).size(), 1u);
  EXPECT_EQ(saturated_colours(b).size(), 2u);
}

TEST(ErrorPlot, RowsWithoutALogarithmAndNoRowsDoNotFail) {
  testing::TempDir dir;
  std::vector<ErrorRow> rows = converging_rows(3, false);
  rows[0].time_s = 0.0;
  rows[1].est_rel_mse = 0.0;
  write_error_plot(dir.path() / "zeros.png", rows, "zeros");
  write_error_plot(dir.path() / "none.png", {}, "no rows");
  for (const char* name : {"zeros.png", "none.png"}) {
    const testing::RgbImage image = testing::read_png_rgb8(dir.path() / name);
    EXPECT_TRUE(image.error.empty()) << name << ": " << image.error;
    EXPECT_GT(image.width, 0u) << name;
  }
}

}  // namespace
}  // namespace rayfarm
