#pragma once
// The "render" section of the JSON format (docs/scene-format.md, "Render"): the scene's default
// render settings.
#include "common/scene/json_reader.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// Reads the "render" object into `settings` (keys it does not give keep their values).
void read_render_settings(const scene_json::Node& n, RenderSettings& settings);

}  // namespace rayfarm
