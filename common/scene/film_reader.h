#pragma once
// The film's reconstruction filter in the JSON format (docs/scene-format.md, "Film"): "filter" is
// a type name or an object with a "type" and the type's parameters; "sample_border" beside it.
#include <optional>

#include "common/scene/json_reader.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// Reads film.filter (absent: the pixel box) and film.sample_border (absent: true).
PixelFilter read_pixel_filter(const std::optional<scene_json::Node>& filter,
                              const std::optional<scene_json::Node>& sample_border);

}  // namespace rayfarm
