#pragma once
// How paths are sampled and ended, as `rayfarm render` and `rayfarm submit` both take it:
// --max-depth (a number or "unlimited"), --sampler, --roulette, --roulette-depth; and the
// shutter of motion blur, --shutter OPEN,CLOSE and --motion-steps.
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <tuple>
#include <utility>

#include <CLI/CLI.hpp>

#include "common/scene/motion.h"
#include "common/scene/scene.h"

namespace rayfarm::cli {

/// "OPEN,CLOSE" in frames after the frame, a shutter that shutter_problem() accepts; nullopt
/// when malformed or not.
inline std::optional<std::pair<float, float>> parse_shutter(const std::string& text) {
  const size_t comma = text.find(',');
  if (comma == std::string::npos) return std::nullopt;
  const auto number = [](const std::string& t) -> std::optional<float> {
    char* end = nullptr;
    const double v = std::strtod(t.c_str(), &end);
    if (t.empty() || end != t.c_str() + t.size()) return std::nullopt;
    return static_cast<float>(v);
  };
  const auto open = number(text.substr(0, comma)), close = number(text.substr(comma + 1));
  if (!open || !close || shutter_problem(*open, *close, kDefaultMotionSteps)) return std::nullopt;
  return std::make_pair(*open, *close);
}

struct SamplingArgs {
  std::optional<std::string> max_depth, sampler, roulette, shutter;
  std::optional<uint32_t> roulette_depth, motion_steps;

  /// The scene's settings with these applied (the options were checked when parsed).
  void apply(RenderSettings& s) const {
    if (max_depth) s.max_depth = *parse_depth(*max_depth);
    if (sampler) s.sampler = *parse_sampler(*sampler);
    if (roulette) s.roulette = *parse_roulette(*roulette);
    if (roulette_depth) s.roulette_depth = *roulette_depth;
    if (shutter) std::tie(s.shutter_open, s.shutter_close) = *parse_shutter(*shutter);
    if (motion_steps) s.motion_steps = *motion_steps;
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
                  "How Russian roulette ends paths: root (on the fourth root of the path's "
                  "throughput from --roulette-depth on, the default), throughput (on the "
                  "throughput itself) or update (on each vertex's BSDF weight)")
      ->check(CLI::IsMember({"root", "throughput", "update"}));
  cmd->add_option("--roulette-depth", args.roulette_depth,
                  "With --roulette root or throughput: the vertex from which roulette may end a path "
                  "(0 = the camera ray's hit; default " +
                      std::to_string(kDefaultRouletteDepth) + ")")
      ->check(CLI::Range(0u, kMaxRouletteDepth));
  cmd->add_option("--shutter", args.shutter,
                  "Motion blur: the shutter is open from OPEN to CLOSE frames after the frame "
                  "(e.g. -0.25,0.25; 0,0 closes it); an animated scene's shapes and camera move "
                  "within it")
      ->check([](const std::string& v) -> std::string {
        return parse_shutter(v)
                   ? std::string()
                   : "OPEN,CLOSE in frames, OPEN <= CLOSE, each within +-100, got '" + v + "'";
      });
  cmd->add_option("--motion-steps", args.motion_steps,
                  "Poses of the scene within an open shutter; moving things move linearly "
                  "between them (default " +
                      std::to_string(kDefaultMotionSteps) + ")")
      ->check(CLI::Range(kMinMotionSteps, kMaxMotionSteps));
}

}  // namespace rayfarm::cli
