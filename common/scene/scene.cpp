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

}  // namespace rayfarm
