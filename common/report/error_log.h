#pragma once
// The error-against-time record of a render: one row per completed pass (or per report tick),
// written as error.csv beside the job's EXR and drawn as error.png (log-log error against time,
// with a 1/t slope for comparison). `rayfarm render`, the master and `rayfarm report` share it.
//
// error.csv columns, in this order (a header line first; empty cell = not measured):
//   time_s, spp, samples_per_s, est_rel_mse, est_rmse, ref_rel_mse, ref_rmse, ref_mae, ref_max
// time_s is wall-clock seconds since the render started; spp is the mean samples per pixel so far
// (fractional when tiles stop adaptively); est_* are estimated from the samples (no reference);
// ref_* are measured against a reference image, when the render has one.
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayfarm {

struct ErrorRow {
  double time_s = 0.0;
  double spp = 0.0;
  double samples_per_s = 0.0;
  double est_rel_mse = 0.0;
  double est_rmse = 0.0;
  std::optional<double> ref_rel_mse, ref_rmse, ref_mae, ref_max;
};

/// A malformed error.csv; what() names the file and the line.
class ErrorLogError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The CSV text of `rows` (header included); numbers printed so they read back exactly.
std::string format_error_csv(const std::vector<ErrorRow>& rows);
/// Writes format_error_csv(rows) atomically (temporary file + rename).
void write_error_csv(const std::filesystem::path& path, const std::vector<ErrorRow>& rows);
/// Reads an error.csv. Throws ErrorLogError naming the file and line on malformed input.
std::vector<ErrorRow> read_error_csv(const std::filesystem::path& path);
std::vector<ErrorRow> parse_error_csv(const std::string& text, const std::string& source);

/// A fixed-width table of `rows` for a terminal (time, spp, samples/s, errors).
std::string format_error_table(const std::vector<ErrorRow>& rows);

/// Draws error.png: estimated relMSE (and measured relMSE, when present) against time on log-log
/// axes, with a 1/t line through the first estimated point. Written atomically. Rows with
/// time 0 or error 0 are left out of the plot (they have no logarithm).
void write_error_plot(const std::filesystem::path& png, const std::vector<ErrorRow>& rows,
                      const std::string& title);

}  // namespace rayfarm
