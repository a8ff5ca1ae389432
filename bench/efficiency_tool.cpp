// The figures of bench/efficiency.sh: time to a clean image, for several renderers that are each
// measured against their own high-spp reference.
//
//   efficiency_tool reference OUT.exr IN.exr IN.exr ...
//     The mean of K >= 2 independent renders, with channels variance.R/G/B holding, per pixel, the
//     variance of that mean estimated from their spread: sum_k (x_k - mean)^2 / (K (K - 1)).
//
//   efficiency_tool analyse RUNS.csv --reference NAME=REF.exr ... [--plot P.png] [--title T]
//     RUNS.csv has the header renderer,round,spp,seconds,cpu_seconds,image (image paths relative
//     to the CSV's folder). Every image's relMSE against its renderer's reference is
//     compare_images' (mean over pixels and channels of (x - ref)^2 / (ref^2 + 1e-2), what
//     `rayfarm render --reference` reports), less the part the reference's own noise adds:
//     E[(x - ref)^2] = var(x) + var(ref) + bias^2, so mean(var_ref / (ref^2 + 1e-2)) is subtracted.
//     Prints per renderer and spp the median time, median relMSE and their product; the product of
//     a converging Monte Carlo render is constant once fixed costs no longer matter, and its median
//     over the ladder's upper half is the renderer's relMSE x time. Efficiency = 1 / (relMSE x
//     time); the ratio is the first renderer's over each other's.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "common/image/exr.h"
#include "common/image/metrics.h"
#include "common/report/plot.h"

namespace fs = std::filesystem;
using namespace rayfarm;

namespace {

constexpr double kRelMseEpsilon = 1e-2;  // compare_images' denominator term

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// ---- reference -------------------------------------------------------------------------------

int make_reference(const std::string& out, const std::vector<std::string>& inputs) {
  if (inputs.size() < 2)
    throw std::runtime_error("a reference needs at least 2 renders to know its variance");
  std::vector<Image> renders;
  for (const std::string& path : inputs) {
    renders.push_back(read_exr(path, {0, 0, true}));
    const Image& a = renders.front();
    const Image& b = renders.back();
    if (b.width != a.width || b.height != a.height) {
      throw std::runtime_error(fmt::format("{}: {}x{}, but {} is {}x{}", path, b.width, b.height,
                                           inputs.front(), a.width, a.height));
    }
  }
  const double k = double(renders.size());
  Image mean;
  mean.width = renders[0].width;
  mean.height = renders[0].height;
  mean.rgb.assign(renders[0].rgb.size(), 0.f);
  const size_t pixels = size_t(mean.width) * mean.height;
  for (int c = 0; c < 3; ++c) mean.extra[std::string("variance.") + "RGB"[c]].assign(pixels, 0.f);
  for (size_t i = 0; i < mean.rgb.size(); ++i) {
    double sum = 0.0;
    for (const Image& r : renders) sum += r.rgb[i];
    const double m = sum / k;
    double spread = 0.0;
    for (const Image& r : renders) spread += (r.rgb[i] - m) * (r.rgb[i] - m);
    mean.rgb[i] = static_cast<float>(m);
    mean.extra[std::string("variance.") + "RGB"[i % 3]][i / 3] =
        static_cast<float>(spread / (k * (k - 1.0)));
  }
  mean.attributes["rayfarm:reference"] =
      fmt::format("mean of {} independent renders", renders.size());
  write_exr(out, mean);
  std::cout << fmt::format("wrote {}: mean of {} renders with the variance of that mean\n", out,
                           renders.size());
  return 0;
}

// ---- analyse ---------------------------------------------------------------------------------

struct Reference {
  Image image;
  double noise = 0.0;  // mean(var_ref / (ref^2 + eps)): what the reference's noise adds to relMSE
};

// The variance of the reference's mean is in its channels variance.R/G/B (`efficiency_tool
// reference`) or, as RGB, in a sibling STEM-variance.exr (scripts/blender_reference.py --seeds K).
Reference load_reference(const std::string& path) {
  Reference ref{read_exr(path), 0.0};
  std::vector<float> var(ref.image.rgb.size());
  const fs::path sibling = fs::path(path).replace_extension().string() + "-variance.exr";
  if (ref.image.extra.count("variance.R") && ref.image.extra.count("variance.G") &&
      ref.image.extra.count("variance.B")) {
    for (int c = 0; c < 3; ++c) {
      const std::vector<float>& v = ref.image.extra.at(std::string("variance.") + "RGB"[c]);
      for (size_t p = 0; p < v.size(); ++p) var[p * 3 + c] = v[p];
    }
  } else if (fs::exists(sibling)) {
    var = read_exr(sibling, {ref.image.width, ref.image.height, true}).rgb;
  } else {
    throw std::runtime_error(path + ": no variance.R/G/B channels and no " + sibling.string() +
                             ": the reference's own noise is unknown");
  }
  for (size_t i = 0; i < var.size(); ++i) {
    const double b = ref.image.rgb[i];
    ref.noise += var[i] / (b * b + kRelMseEpsilon);
  }
  ref.noise /= double(var.size());
  return ref;
}

struct Run {
  std::string renderer;
  int round = 0;
  uint32_t spp = 0;
  double seconds = 0.0, cpu_seconds = 0.0;
  std::string image;
  double rel_mse_measured = 0.0, rel_mse = 0.0;
};

std::vector<Run> read_runs(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::string line;
  std::getline(in, line);
  if (line != "renderer,round,spp,seconds,cpu_seconds,image") {
    throw std::runtime_error(
        path + ":1: expected the header renderer,round,spp,seconds,cpu_seconds,image");
  }
  std::vector<Run> runs;
  for (int line_no = 2; std::getline(in, line); ++line_no) {
    if (line.empty()) continue;
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
    Run r;
    try {
      if (f.size() != 6) throw std::invalid_argument("6 fields");
      r.renderer = f[0];
      r.round = std::stoi(f[1]);
      r.spp = static_cast<uint32_t>(std::stoul(f[2]));
      r.seconds = std::stod(f[3]);
      r.cpu_seconds = f[4].empty() ? std::nan("") : std::stod(f[4]);
      r.image = (fs::path(path).parent_path() / f[5]).string();
    } catch (const std::exception&) {
      throw std::runtime_error(fmt::format(
          "{}:{}: expected renderer,round,spp,seconds,cpu_seconds,image", path, line_no));
    }
    if (!(r.seconds > 0))
      throw std::runtime_error(fmt::format("{}:{}: seconds must be > 0", path, line_no));
    runs.push_back(std::move(r));
  }
  if (runs.empty()) throw std::runtime_error(path + ": no runs");
  return runs;
}

struct Level {
  uint32_t spp = 0;
  size_t rounds = 0;
  double seconds = 0.0, cpu_seconds = 0.0, rel_mse = 0.0, rel_mse_measured = 0.0;
  double product() const { return rel_mse * seconds; }
};

struct Curve {
  std::vector<Level> levels;  // by spp
  double product = 0.0;       // median relMSE x time over the upper half of the ladder
  double product_cpu = 0.0;   // the same with CPU seconds (less sensitive to a shared machine)
  std::optional<double> upper_slope;
};

Curve summarise(const std::vector<Run>& runs, const std::string& renderer) {
  std::map<uint32_t, std::vector<const Run*>> by_spp;
  for (const Run& r : runs) {
    if (r.renderer == renderer) by_spp[r.spp].push_back(&r);
  }
  Curve curve;
  for (const auto& [spp, rs] : by_spp) {
    std::vector<double> t, cpu, e, m;
    for (const Run* r : rs) {
      t.push_back(r->seconds);
      cpu.push_back(r->cpu_seconds);
      e.push_back(r->rel_mse);
      m.push_back(r->rel_mse_measured);
    }
    curve.levels.push_back({spp, rs.size(), median(t), median(cpu), median(e), median(m)});
  }
  std::vector<double> upper, upper_cpu;
  std::vector<PlotPoint> upper_points;
  for (size_t i = curve.levels.size() / 2; i < curve.levels.size(); ++i) {
    const Level& l = curve.levels[i];
    upper.push_back(l.product());
    if (std::isfinite(l.cpu_seconds)) upper_cpu.push_back(l.rel_mse * l.cpu_seconds);
    upper_points.emplace_back(l.seconds, l.rel_mse);
  }
  curve.product = median(upper);
  curve.product_cpu = median(upper_cpu);
  curve.upper_slope = loglog_slope(upper_points);
  return curve;
}

int analyse(const std::string& runs_path, const std::vector<std::string>& reference_args,
            const std::string& plot_path, const std::string& title, const std::string& out_csv) {
  std::map<std::string, Reference> references;
  std::vector<std::string> order;  // renderers in the order of --reference
  for (const std::string& arg : reference_args) {
    const size_t eq = arg.find('=');
    if (eq == std::string::npos || eq == 0)
      throw std::runtime_error("--reference " + arg + ": expected NAME=FILE.exr");
    const std::string name = arg.substr(0, eq);
    references[name] = load_reference(arg.substr(eq + 1));
    order.push_back(name);
  }
  std::vector<Run> runs = read_runs(runs_path);
  for (Run& r : runs) {
    const auto ref = references.find(r.renderer);
    if (ref == references.end())
      throw std::runtime_error(runs_path + ": no --reference for renderer " + r.renderer);
    const ImageDiff d = compare_images(read_exr(r.image, {0, 0, true}), ref->second.image);
    r.rel_mse_measured = d.rel_mse;
    // Kept positive for the logarithms; a correction over half the measurement is reported below.
    r.rel_mse = std::max(d.rel_mse - ref->second.noise, 0.05 * d.rel_mse);
  }
  if (!out_csv.empty()) {
    std::ofstream csv(out_csv);
    csv << "renderer,round,spp,seconds,cpu_seconds,rel_mse,rel_mse_measured,reference_noise,"
           "image\n";
    for (const Run& r : runs) {
      csv << fmt::format("{},{},{},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{}\n", r.renderer, r.round,
                         r.spp, r.seconds, r.cpu_seconds, r.rel_mse, r.rel_mse_measured,
                         references[r.renderer].noise, fs::path(r.image).filename().string());
    }
    if (!csv) throw std::runtime_error("cannot write " + out_csv);
  }

  std::map<std::string, Curve> curves;
  for (const std::string& name : order) {
    const Reference& ref = references[name];
    const Curve c = summarise(runs, name);
    if (c.levels.empty()) continue;
    curves[name] = c;
    std::cout << fmt::format("\n{}: reference noise relMSE {:.3g} (subtracted)\n", name, ref.noise);
    std::cout << "| spp | rounds | median time (s) | median CPU (s) | median relMSE | relMSE x "
                 "time (s) |\n"
                 "| ---: | ---: | ---: | ---: | ---: | ---: |\n";
    bool noisy_reference = false;
    for (const Level& l : c.levels) {
      std::cout << fmt::format("| {} | {} | {:.3g} | {:.3g} | {:.3g} | {:.3g} |\n", l.spp, l.rounds,
                               l.seconds, l.cpu_seconds, l.rel_mse, l.product());
      noisy_reference |= ref.noise > 0.5 * l.rel_mse_measured;
    }
    if (noisy_reference) {
      std::cout << "warning: the reference's own noise is over half of some measured relMSE: "
                   "give it more samples\n";
    }
    std::cout << fmt::format(
        "{}: relMSE x time {:.4g} s (median over the upper {} spp levels; their log-log "
        "slope {}), efficiency 1/(relMSE x time) = {:.4g} /s; relMSE x CPU time {:.4g} s\n",
        name, c.product, c.levels.size() - c.levels.size() / 2,
        c.upper_slope ? fmt::format("{:.2f}", *c.upper_slope) : "-", 1.0 / c.product,
        c.product_cpu);
  }
  if (curves.size() >= 2) {
    const std::string& first = order.front();
    for (const auto& [name, c] : curves) {
      if (name == first) continue;
      std::cout << fmt::format("efficiency ratio {}/{}: {:.3g} (wall time); {:.3g} (CPU time)\n",
                               first, name, c.product / curves[first].product,
                               c.product_cpu / curves[first].product_cpu);
    }
  }

  if (!plot_path.empty()) {
    LogLogPlot plot;
    plot.title = title;
    plot.x_label = "render time (s, median of the rounds)";
    plot.y_label = "relMSE";
    const PlotColor colours[] = {{40, 80, 200}, {200, 60, 40}, {40, 140, 60}, {120, 60, 160}};
    size_t k = 0;
    for (const std::string& name : order) {
      if (!curves.count(name)) continue;
      PlotSeries s{name, colours[k++ % 4], {}};
      for (const Level& l : curves[name].levels) s.points.emplace_back(l.seconds, l.rel_mse);
      plot.series.push_back(std::move(s));
    }
    if (!plot.series.empty() && !plot.series.front().points.empty()) {
      plot.slope_line = SlopeLine{"1/t", plot.series.front().points.back()};
    }
    write_plot_png(plot, plot_path);
    std::cout << "wrote " << plot_path << "\n";
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"efficiency_tool: references and relMSE x time figures for bench/efficiency.sh"};
  app.require_subcommand(1);
  std::string out, runs_path, plot_path, title, out_csv;
  std::vector<std::string> inputs, reference_args;
  CLI::App* ref = app.add_subcommand("reference",
                                     "Mean of independent renders, with the variance of that mean");
  ref->add_option("out", out, "Output EXR")->required();
  ref->add_option("inputs", inputs, "Renders (EXR), at least 2")->required();
  CLI::App* an = app.add_subcommand(
      "analyse", "relMSE of each run against its renderer's reference; medians, ratio, plot");
  an->add_option("runs", runs_path, "CSV: renderer,round,spp,seconds,cpu_seconds,image")
      ->required();
  an->add_option("--reference", reference_args,
                 "NAME=REF.exr, one per renderer; the first is the ratio's numerator")
      ->required();
  an->add_option("--plot", plot_path, "Plot PNG of relMSE against time");
  an->add_option("--title", title, "Plot title");
  an->add_option("--csv", out_csv, "Per-image results CSV");
  CLI11_PARSE(app, argc, argv);
  try {
    if (ref->parsed()) return make_reference(out, inputs);
    return analyse(runs_path, reference_args, plot_path, title, out_csv);
  } catch (const std::exception& e) {
    std::cerr << "efficiency_tool: " << e.what() << "\n";
    return 1;
  }
}
