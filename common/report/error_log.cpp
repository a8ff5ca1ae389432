#include "common/report/error_log.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <string_view>
#include <system_error>

#include <fmt/format.h>

#include "common/report/plot.h"
#include "common/util/atomic_file.h"
#include "common/util/read_file.h"

namespace rayfarm {
namespace {

constexpr size_t kColumns = 9;
constexpr std::array<std::string_view, kColumns> kHeader = {
    "time_s",      "spp",      "samples_per_s", "est_rel_mse", "est_rmse",
    "ref_rel_mse", "ref_rmse", "ref_mae",       "ref_max"};
constexpr size_t kRequired = 5;  // the first five columns may not be empty

/// Cells of one CSV line (no quoting: every cell is a number or empty), trimmed of blanks.
std::vector<std::string_view> split_cells(std::string_view line) {
  std::vector<std::string_view> cells;
  while (true) {
    const size_t comma = line.find(',');
    std::string_view cell = line.substr(0, comma);
    while (!cell.empty() && (cell.front() == ' ' || cell.front() == '\t')) cell.remove_prefix(1);
    while (!cell.empty() && (cell.back() == ' ' || cell.back() == '\t')) cell.remove_suffix(1);
    cells.push_back(cell);
    if (comma == std::string_view::npos) return cells;
    line.remove_prefix(comma + 1);
  }
}

std::string header_line() {
  std::string line;
  for (size_t i = 0; i < kColumns; ++i) {
    if (i) line += ',';
    line += kHeader[i];
  }
  return line;
}

/// The shortest text that reads back as exactly `value`.
std::string number(double value) { return fmt::format("{}", value); }

std::string optional_number(const std::optional<double>& value) {
  return value ? number(*value) : std::string();
}

/// One table column: its title and the text of each row's value.
struct TableColumn {
  std::string title;
  std::vector<std::string> cells;
};

std::string table_number(const std::optional<double>& value, const char* format) {
  if (!value) return "-";
  return fmt::format(fmt::runtime(format), *value);
}

/// Samples per pixel: a whole number as such, a fraction (adaptive stopping) with two decimals.
std::string table_spp(double spp) {
  if (std::isfinite(spp) && spp == std::floor(spp) && std::abs(spp) < 1e15) {
    return fmt::format("{:.0f}", spp);
  }
  return fmt::format("{:.2f}", spp);
}

}  // namespace

std::string format_error_csv(const std::vector<ErrorRow>& rows) {
  std::string text = header_line() + "\n";
  for (const ErrorRow& r : rows) {
    text += fmt::format("{},{},{},{},{},{},{},{},{}\n", number(r.time_s), number(r.spp),
                        number(r.samples_per_s), number(r.est_rel_mse), number(r.est_rmse),
                        optional_number(r.ref_rel_mse), optional_number(r.ref_rmse),
                        optional_number(r.ref_mae), optional_number(r.ref_max));
  }
  return text;
}

void write_error_csv(const std::filesystem::path& path, const std::vector<ErrorRow>& rows) {
  write_file_atomically(path, format_error_csv(rows));
}

std::vector<ErrorRow> read_error_csv(const std::filesystem::path& path) {
  std::string text;
  try {
    text = read_whole_file(path, kNoSizeCap);
  } catch (const FileReadError& e) {
    const bool missing = e.kind() == FileReadError::Kind::kNotFound;
    throw ErrorLogError(
        fmt::format("cannot read {}: {}", path.string(), missing ? "no such file" : e.what()));
  }
  return parse_error_csv(text, path.string());
}

std::vector<ErrorRow> parse_error_csv(const std::string& text, const std::string& source) {
  const auto fail = [&source](size_t line, const std::string& cause) {
    return ErrorLogError(fmt::format("{}:{}: {}", source, line, cause));
  };
  std::vector<ErrorRow> rows;
  bool header_seen = false;
  size_t line_number = 0;
  std::string_view rest = text;
  while (!rest.empty()) {
    ++line_number;
    const size_t newline = rest.find('\n');
    std::string_view line = rest.substr(0, newline);
    rest.remove_prefix(newline == std::string_view::npos ? rest.size() : newline + 1);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.find_first_not_of(" \t") == std::string_view::npos) continue;  // blank line

    const std::vector<std::string_view> cells = split_cells(line);
    if (!header_seen) {
      if (cells.size() != kColumns || !std::equal(cells.begin(), cells.end(), kHeader.begin())) {
        throw fail(line_number,
                   fmt::format("expected the header line '{}', found '{}'", header_line(), line));
      }
      header_seen = true;
      continue;
    }
    if (cells.size() != kColumns) {
      throw fail(line_number,
                 fmt::format("{} cells, expected {} ({})", cells.size(), kColumns, header_line()));
    }
    std::array<std::optional<double>, kColumns> values;
    for (size_t i = 0; i < kColumns; ++i) {
      const std::string_view cell = cells[i];
      if (cell.empty()) {
        if (i < kRequired) throw fail(line_number, fmt::format("{} is empty", kHeader[i]));
        continue;
      }
      double value = 0.0;
      const auto [end, ec] = std::from_chars(cell.data(), cell.data() + cell.size(), value);
      if (ec != std::errc() || end != cell.data() + cell.size()) {
        throw fail(line_number, fmt::format("{}: '{}' is not a number", kHeader[i], cell));
      }
      values[i] = value;
    }
    rows.push_back(ErrorRow{*values[0], *values[1], *values[2], *values[3], *values[4], values[5],
                            values[6], values[7], values[8]});
  }
  if (!header_seen) {
    throw fail(1, fmt::format("no header line '{}' (empty file)", header_line()));
  }
  return rows;
}

std::string format_error_table(const std::vector<ErrorRow>& rows) {
  const bool any_reference = std::any_of(rows.begin(), rows.end(), [](const ErrorRow& r) {
    return r.ref_rel_mse || r.ref_rmse || r.ref_mae || r.ref_max;
  });
  std::vector<TableColumn> columns = {
      {"time (s)", {}}, {"spp", {}}, {"samples/s", {}}, {"est relMSE", {}}, {"est RMSE", {}}};
  if (any_reference) {
    for (const char* title : {"ref relMSE", "ref RMSE", "ref MAE", "ref max"}) {
      columns.push_back({title, {}});
    }
  }
  for (const ErrorRow& r : rows) {
    columns[0].cells.push_back(table_number(r.time_s, "{:.3f}"));
    columns[1].cells.push_back(table_spp(r.spp));
    columns[2].cells.push_back(table_number(r.samples_per_s, "{:.0f}"));
    columns[3].cells.push_back(table_number(r.est_rel_mse, "{:.3e}"));
    columns[4].cells.push_back(table_number(r.est_rmse, "{:.3e}"));
    if (any_reference) {
      columns[5].cells.push_back(table_number(r.ref_rel_mse, "{:.3e}"));
      columns[6].cells.push_back(table_number(r.ref_rmse, "{:.3e}"));
      columns[7].cells.push_back(table_number(r.ref_mae, "{:.3e}"));
      columns[8].cells.push_back(table_number(r.ref_max, "{:.3e}"));
    }
  }
  // Every column right-aligned to its widest entry, two spaces apart.
  std::vector<size_t> widths;
  for (const TableColumn& c : columns) {
    size_t width = c.title.size();
    for (const std::string& cell : c.cells) width = std::max(width, cell.size());
    widths.push_back(width);
  }
  std::string table;
  for (size_t row = 0; row <= rows.size(); ++row) {
    std::string line;
    for (size_t i = 0; i < columns.size(); ++i) {
      const std::string& text = row == 0 ? columns[i].title : columns[i].cells[row - 1];
      line += fmt::format("{}{:>{}}", i ? "  " : "", text, widths[i]);
    }
    table += line + "\n";
  }
  return table;
}

void write_error_plot(const std::filesystem::path& png, const std::vector<ErrorRow>& rows,
                      const std::string& title) {
  LogLogPlot plot;
  plot.title = title;
  plot.x_label = "time (s)";
  plot.y_label = "relative MSE";
  PlotSeries estimated{"estimated relMSE", {30, 100, 200}, {}};
  PlotSeries measured{"measured relMSE (reference)", {210, 60, 40}, {}};
  for (const ErrorRow& r : rows) {
    estimated.points.emplace_back(r.time_s, r.est_rel_mse);
    if (r.ref_rel_mse) measured.points.emplace_back(r.time_s, *r.ref_rel_mse);
  }
  // The 1/t line through the first point that has a place on the axes.
  const auto first = std::find_if(estimated.points.begin(), estimated.points.end(),
                                  [](const PlotPoint& p) { return p.first > 0 && p.second > 0; });
  if (first != estimated.points.end() && std::isfinite(first->first) &&
      std::isfinite(first->second)) {
    plot.slope_line = SlopeLine{"1/t", *first, -1.0};
  }
  plot.series.push_back(std::move(estimated));
  if (!measured.points.empty()) plot.series.push_back(std::move(measured));
  write_plot_png(plot, png);
}

}  // namespace rayfarm
