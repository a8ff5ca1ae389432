#pragma once
// How paths are sampled and ended, as `rayfarm render` and `rayfarm submit` both take it:
// --max-depth (a number or "unlimited"), --sampler, --roulette, --roulette-depth.
#include <cstdint>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "common/scene/scene.h"

namespace rayfarm::cli {

struct SamplingArgs {
  std::optional<std::string> max_depth, sampler, roulette;
  std::optional<uint32_t> roulette_depth;

  /// The scene's settings with these applied (the options were checked when parsed).
  void apply(RenderSettings& s) const {
    if (max_depth) s.max_depth = *parse_depth(*max_depth);
    if (sampler) s.sampler = *parse_sampler(*sampler);
    if (roulette) s.roulette = *parse_roulette(*roulette);
    if (roulette_depth) s.roulette_depth = *roulette_depth;
  }
};

inline void add_sampling_options(CLI::App* cmd, SamplingArgs& args) {
  cmd->add_option("--max-depth", args.max_depth,
                  "Most scattering vertices per path, or 'unlimited' (Russian roulette alone "
                  "ends paths; the default unless the scene says)")
      ->check([](const std::string& v) -> std::string {
        return parse_depth(v) ? std::string()
                              : "a number in [0, " + std::to_string(kMaxDepth) +
                                    "] or 'unlimited', got '" + v + "'";
      });
  cmd->add_option("--sampler", args.sampler,
                  "sobol (scrambled low-discrepancy points, the default) or independent (one "
                  "random stream per sample)")
      ->check(CLI::IsMember({"sobol", "independent"}));
  cmd->add_option("--roulette", args.roulette,
                  "How Russian roulette ends paths: throughput (on the path's throughput from "
                  "--roulette-depth on, the default) or update (on each vertex's BSDF weight)")
      ->check(CLI::IsMember({"throughput", "update"}));
  cmd->add_option("--roulette-depth", args.roulette_depth,
                  "With --roulette throughput: the vertex from which roulette may end a path "
                  "(0 = the camera ray's hit; default " +
                      std::to_string(kDefaultRouletteDepth) + ")")
      ->check(CLI::Range(0u, kMaxRouletteDepth));
}

}  // namespace rayfarm::cli
