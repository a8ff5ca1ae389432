// `rayfarm report TARGET [-o PLOT.png]`: the error-against-time record of a render, as a table,
// a summary (last error, log-log slope, why the job stopped) and a plot. TARGET is an error.csv
// on this machine or a job id on the master (fetched like `rayfarm fetch`).
#include <cmath>
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/farm_client.h"
#include "common/protocol/convert.h"
#include "common/report/error_log.h"
#include "common/report/plot.h"
#include "common/util/atomic_file.h"

namespace rayfarm::cli {
namespace {
namespace fs = std::filesystem;

constexpr int kExitError = 1;

struct ReportArgs {
  std::string target;
  std::string output;  ///< -o; "" = the default
  JobFetcher fetch;
  bool json = false;  ///< rows as JSON lines on stdout; the other lines go to stderr

  /// Where the lines besides the rows go.
  std::ostream& text() const { return json ? std::cerr : std::cout; }
};

/// A CSV path rather than a job id: an existing file, a .csv name, or anything with a folder.
bool is_local_file(const std::string& target) {
  std::error_code ec;
  return fs::exists(target, ec) || fs::path(target).extension() == ".csv" ||
         target.find('/') != std::string::npos;
}

/// The log-log slope of the estimated relMSE against time over the second half of the rows,
/// where the start-up (first passes, scheduling) no longer weighs; about -1 for an unbiased
/// render.
std::optional<double> late_slope(const std::vector<ErrorRow>& rows) {
  std::vector<PlotPoint> points;
  for (size_t i = rows.size() / 2; i < rows.size(); ++i) {
    points.emplace_back(rows[i].time_s, rows[i].est_rel_mse);
  }
  return loglog_slope(points);
}

/// "12 rows, 52.8 s, 128 spp; last est relMSE 8.5e-04 (measured 1.3e-03); slope -1.02 ..."
std::string summary_line(const std::vector<ErrorRow>& rows) {
  const ErrorRow& last = rows.back();
  std::string line = fmt::format(
      "{} rows, {:.3g} s, {:.4g} spp; last est relMSE {}", rows.size(), last.time_s, last.spp,
      std::isfinite(last.est_rel_mse) ? fmt::format("{:.3e}", last.est_rel_mse) : "-");
  if (last.ref_rel_mse) line += fmt::format(" (measured {:.3e})", *last.ref_rel_mse);
  const size_t late = rows.size() - rows.size() / 2;
  if (const auto slope = late_slope(rows)) {
    line += fmt::format("; log-log slope {:.2f} over the last {} rows (about -1 when unbiased)",
                        *slope, late);
  } else {
    line += "; log-log slope: too few rows to fit";
  }
  return line;
}

nlohmann::json optional_figure(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

void print_report(const std::vector<ErrorRow>& rows, const ReportArgs& args) {
  if (args.json) {
    for (const ErrorRow& r : rows) {
      std::cout << nlohmann::json{{"time_s", r.time_s},
                                  {"spp", r.spp},
                                  {"samples_per_s", r.samples_per_s},
                                  {"est_rel_mse", r.est_rel_mse},
                                  {"est_rmse", r.est_rmse},
                                  {"ref_rel_mse", optional_figure(r.ref_rel_mse)},
                                  {"ref_rmse", optional_figure(r.ref_rmse)},
                                  {"ref_mae", optional_figure(r.ref_mae)},
                                  {"ref_max", optional_figure(r.ref_max)}}
                       .dump()
                << "\n";
    }
    std::cerr << summary_line(rows) << "\n";
    return;
  }
  std::cout << format_error_table(rows) << summary_line(rows) << "\n";
}

int report_file(const ReportArgs& args) {
  const fs::path csv = args.target;
  const std::vector<ErrorRow> rows = read_error_csv(csv);
  if (rows.empty()) {
    std::cerr << fmt::format("rayfarm report: error: {} has no rows yet\n", csv.string());
    return kExitError;
  }
  print_report(rows, args);
  if (!args.output.empty()) {
    write_error_plot(args.output, rows, csv.string());
    args.text() << fmt::format("plot: {}\n", args.output);
    return 0;
  }
  // The plot the render wrote beside its error.csv.
  fs::path beside = csv;
  beside.replace_extension(".png");
  std::error_code ec;
  if (fs::exists(beside, ec)) {
    args.text() << fmt::format("plot: {}\n", beside.string());
  } else {
    args.text() << fmt::format("plot: none beside {} (draw one with -o PLOT.png)\n", csv.string());
  }
  return 0;
}

/// "done, stopped by target error; 96.0 spp mean; tiles converged 40/64; est relMSE 1.0e-03"
std::string job_line(const wire::JobStatus& st) {
  std::string line =
      fmt::format("job {}{}: {}", st.job_id(), st.name().empty() ? "" : " (" + st.name() + ")",
                  protocol::job_state_name(st.state()));
  if (!st.stop_reason().empty()) line += ", stopped by " + st.stop_reason();
  line += fmt::format("; {:.1f} spp mean", st.spp_mean());
  if (st.tiles_total() > 0) {
    line += fmt::format("; tiles converged {}/{}", st.tiles_converged(), st.tiles_total());
  }
  // (not finite: unknown, e.g. a job cancelled before a pixel had two samples)
  line += "; est relMSE " + (std::isfinite(st.est_rel_mse()) && st.est_rel_mse() >= 0
                                 ? fmt::format("{:.3e}", st.est_rel_mse())
                                 : std::string("-"));
  if (st.ref_rel_mse() >= 0 && std::isfinite(st.ref_rel_mse()))
    line += fmt::format("; measured relMSE {:.3e}", st.ref_rel_mse());
  return line;
}

int report_job(const ReportArgs& args) {
  const JobSnapshot job = args.fetch(args.target);
  const wire::JobStatus& st = job.status;
  std::vector<ErrorRow> rows;
  if (job.image && !job.image->error_csv().empty()) {
    rows = parse_error_csv(job.image->error_csv(), "job " + args.target + " error.csv");
  }
  if (rows.empty()) {
    std::string why =
        job.no_image_reason.empty() ? "" : "; the master says: " + job.no_image_reason;
    std::cerr << fmt::format("rayfarm report: error: job {} has no error rows yet{}\n", args.target,
                             why)
              << job_line(st) << "\n";
    return kExitError;
  }
  print_report(rows, args);
  args.text() << job_line(st) << "\n";

  const fs::path plot = args.output.empty() ? args.target + "-error.png" : args.output;
  if (!job.image->error_png().empty()) {
    write_file_atomically(plot, job.image->error_png());  // the plot the master drew
  } else {
    write_error_plot(plot, rows, fmt::format("job {} {}", st.job_id(), st.name()));
  }
  args.text() << fmt::format("plot: {}\n", plot.string());
  return 0;
}

}  // namespace

void add_report_command(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ReportArgs>();
  CLI::App* cmd = app.add_subcommand(
      "report", "Error against time of a render: table, summary and log-log plot");
  cmd->add_option("target", args->target, "An error.csv file, or a job id on the master")
      ->required();
  cmd->add_option("-o,--output", args->output,
                  "Plot to write (PNG). Default for a job: JOB-error.png here; for a file: "
                  "none, the error.png beside it is shown");
  args->fetch = add_job_fetch_options(cmd);
  cmd->add_flag("--json", args->json,
                "The rows as JSON, one object per line (docs/cli.md); the summary goes to stderr");
  cmd->callback([args, &exit_code] {
    exit_code = run_farm_command("report", [&] {
      return is_local_file(args->target) ? report_file(*args) : report_job(*args);
    });
  });
}

}  // namespace rayfarm::cli
