#include "renderer/lights/light_selection.h"

namespace rayfarm {

LightSelection::LightSelection(const std::vector<double>& powers,
                               const std::vector<std::optional<LightBounds>>& bounds,
                               LightChoice choice) {
  std::vector<LightBounds> placed;
  std::vector<int32_t> placed_index;
  for (size_t i = 0; i < bounds.size(); ++i) {
    if (!bounds[i]) continue;
    LightBounds b = *bounds[i];
    b.intensity = std::max(b.intensity, 1e-30);  // as by power: every light keeps a share
    placed.push_back(b);
    placed_index.push_back(static_cast<int32_t>(i));
  }
  const bool tree =
      !placed.empty() && (choice == LightChoice::kTree ||
                          (choice == LightChoice::kAuto && placed.size() >= kTreeMinLights));
  if (!tree) {
    power_ = PowerLightSelection(powers);
    return;
  }
  tree_ = LightTree(placed, placed_index);
  std::vector<bool> in_tree(powers.size(), false);
  group_.assign(powers.size(), 0);
  double tree_power = 0.0;
  for (const int32_t i : placed_index) {
    in_tree[i] = true;
    tree_power += std::max(powers[i], 1e-30);
  }
  std::vector<double> group_powers{tree_power};
  for (size_t i = 0; i < powers.size(); ++i) {
    if (in_tree[i]) continue;
    group_[i] = static_cast<int32_t>(group_powers.size());
    infinite_.push_back(static_cast<int32_t>(i));
    group_powers.push_back(powers[i]);
  }
  groups_ = PowerLightSelection(group_powers);
}

}  // namespace rayfarm
