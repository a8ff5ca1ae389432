#include "common/scene/scene.h"

#include <algorithm>

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

bool has_light(const Scene& scene) {
  if (!scene.point_lights.empty() || !scene.spot_lights.empty() ||
      !scene.directional_lights.empty() || !is_black(scene.background))
    return true;
  if (scene.environment && !is_black(scene.environment->scale)) return true;
  auto emits = [&](uint32_t material) {
    return material < scene.materials.size() && scene.materials[material].is_emissive();
  };
  auto mesh_emits = [&](const TriangleMesh& mesh) {
    return std::any_of(mesh.materials.begin(), mesh.materials.end(), emits);
  };
  if (std::any_of(scene.meshes.begin(), scene.meshes.end(), mesh_emits)) return true;
  for (const Sphere& s : scene.spheres)
    if (emits(s.material)) return true;
  // A group lights the scene when some instance places it: each group looked at once.
  std::vector<uint8_t> placed(scene.groups.size(), 0);
  for (const Instance& instance : scene.instances)
    if (instance.group < placed.size()) placed[instance.group] = 1;
  for (size_t g = 0; g < placed.size(); ++g) {
    const std::vector<TriangleMesh>& meshes = scene.groups[g].meshes;
    if (placed[g] && std::any_of(meshes.begin(), meshes.end(), mesh_emits)) return true;
  }
  return false;
}

}  // namespace rayfarm
