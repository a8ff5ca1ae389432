#pragma once
// The JSON scene's "camera" (docs/scene-format.md, "Camera"): perspective or orthographic, checked
// to have a view direction and an up that is not along it.
#include "common/scene/json_reader.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// The camera `n` describes; the defaults of Camera for what it leaves out.
Camera read_camera(const scene_json::Node& n);

}  // namespace rayfarm
