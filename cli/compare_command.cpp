// `rayfarm compare TEST.exr REFERENCE.exr`: error metrics of an image against a reference.
// Exit code, as cmp's: 0 when bit-identical, 1 when the images differ or an image cannot be read
// (an error, named on stderr, with nothing on stdout: docs/cli.md, "Exit codes"); 2 is a usage
// error, as for every command.
#include <cmath>
#include <exception>
#include <iostream>
#include <memory>
#include <string>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "common/image/exr.h"
#include "common/image/metrics.h"

namespace rayfarm::cli {
namespace {

constexpr int kIdentical = 0;
constexpr int kDifferent = 1;
constexpr int kError = 1;

struct CompareOptions {
  std::string test;
  std::string reference;
  bool json = false;
};

/// A metric for JSON, which has no infinity: non-finite values become null.
nlohmann::json json_number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

void print_json(const CompareOptions& options, const Image& reference, const ImageDiff& diff) {
  const nlohmann::ordered_json out = {
      {"test", options.test},           {"reference", options.reference},
      {"width", reference.width},       {"height", reference.height},
      {"rmse", json_number(diff.rmse)}, {"rel_mse", json_number(diff.rel_mse)},
      {"mae", json_number(diff.mae)},   {"max_abs", json_number(diff.max_abs)},
      {"differing", diff.differing},    {"nan_values", diff.nan_values},
      {"values", diff.values},          {"identical", diff.identical},
  };
  std::cout << out.dump() << "\n";
}

void print_text(const CompareOptions& options, const Image& reference, const ImageDiff& diff) {
  std::cout << fmt::format("test:               {}\n", options.test)
            << fmt::format("reference:          {} ({}x{})\n", options.reference, reference.width,
                           reference.height)
            << fmt::format("RMSE:               {:.6e}\n", diff.rmse)
            << fmt::format("relative MSE:       {:.6e}\n", diff.rel_mse)
            << fmt::format("MAE:                {:.6e}\n", diff.mae)
            << fmt::format("max abs difference: {:.6e}\n", diff.max_abs)
            << fmt::format("differing values:   {} of {}\n", diff.differing, diff.values);
  if (diff.nan_values > 0) std::cout << fmt::format("NaN values:         {}\n", diff.nan_values);
  std::cout << fmt::format("identical: {}\n", diff.identical ? "yes" : "no");
}

int run_compare(const CompareOptions& options) {
  try {
    const Image test = read_exr(options.test);
    const Image reference = read_exr(options.reference);
    const ImageDiff diff = compare_images(test, reference);
    if (options.json) {
      print_json(options, reference, diff);
    } else {
      print_text(options, reference, diff);
    }
    return diff.identical ? kIdentical : kDifferent;
  } catch (const std::exception& e) {
    std::cerr << "rayfarm compare: error: " << e.what() << "\n";
    return kError;
  }
}

}  // namespace

void add_compare_command(CLI::App& app, int& exit_code) {
  auto options = std::make_shared<CompareOptions>();
  CLI::App* command = app.add_subcommand(
      "compare",
      "Compare an image to a reference: RMSE, relative MSE, MAE, max difference. "
      "Exit code 0 when bit-identical, 1 when different or on an error (named on stderr).");
  command->add_option("test", options->test, "image to check (EXR)")->required();
  command->add_option("reference", options->reference, "reference image (EXR)")->required();
  command->add_flag("--json", options->json, "print the metrics as one JSON object");
  command->callback([options, &exit_code] { exit_code = run_compare(*options); });
}

}  // namespace rayfarm::cli
