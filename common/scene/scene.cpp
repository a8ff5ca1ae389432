#include "common/scene/scene.h"

namespace rayfarm {

const char* integrator_name(IntegratorType type) {
  switch (type) {
    case IntegratorType::kNaive: return "naive";
    case IntegratorType::kNee: return "nee";
    case IntegratorType::kMis: return "mis";
  }
  return "unknown";
}

std::optional<IntegratorType> parse_integrator(const std::string& name) {
  if (name == "naive") return IntegratorType::kNaive;
  if (name == "nee") return IntegratorType::kNee;
  if (name == "mis") return IntegratorType::kMis;
  return std::nullopt;
}

const char* filter_name(FilterType type) {
  switch (type) {
    case FilterType::kBox:
      return "box";
    case FilterType::kTent:
      return "tent";
    case FilterType::kGaussian:
      return "gaussian";
    case FilterType::kMitchell:
      return "mitchell";
    case FilterType::kLanczos:
      return "lanczos";
    case FilterType::kBlackmanHarris:
      return "blackman-harris";
  }
  return "unknown";
}

const char* sampler_name(SamplerType type) {
  return type == SamplerType::kSobol ? "sobol" : "independent";
}

std::optional<SamplerType> parse_sampler(const std::string& name) {
  if (name == "sobol") return SamplerType::kSobol;
  if (name == "independent") return SamplerType::kIndependent;
  return std::nullopt;
}

const char* roulette_name(RouletteType type) {
  switch (type) {
    case RouletteType::kThroughput: return "throughput";
    case RouletteType::kRoot: return "root";
    case RouletteType::kUpdate: break;
  }
  return "update";
}

std::optional<RouletteType> parse_roulette(const std::string& name) {
  if (name == "root") return RouletteType::kRoot;
  if (name == "throughput") return RouletteType::kThroughput;
  if (name == "update") return RouletteType::kUpdate;
  return std::nullopt;
}

std::string depth_name(uint32_t max_depth) {
  return max_depth == kUnlimitedDepth ? "unlimited" : std::to_string(max_depth);
}

std::optional<uint32_t> parse_depth(const std::string& text) {
  if (text == "unlimited") return kUnlimitedDepth;
  if (text.empty() || text.size() > 10 || text.find_first_not_of("0123456789") != std::string::npos)
    return std::nullopt;
  const uint64_t v = std::stoull(text);
  if (v > kMaxDepth) return std::nullopt;
  return static_cast<uint32_t>(v);
}

}  // namespace rayfarm
