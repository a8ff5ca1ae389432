#pragma once
// Mitsuba 3 XML scenes (docs/mitsuba.md): read into rayfarm's Scene, so that they render locally
// and on the farm like any other scene. What rayfarm cannot render as Mitsuba would is an error
// naming the file, the line and the element; what changes nothing it renders is a warning.
#include <filesystem>

#include "common/scene/mitsuba_xml.h"
#include "common/scene/scene_files.h"
#include "common/scene/texture_reader.h"

namespace rayfarm {

/// Loads the Mitsuba scene `file`. Every file it reads must lie under `root` (empty: the scene's
/// folder). `parameters` give $name values that the scene's <default>s do not override.
/// Throws SceneError (SceneRefused when `check` refuses the film or the render settings).
Scene load_mitsuba_scene(const std::filesystem::path& file, const SceneCheck& check,
                         SceneImages images, const std::filesystem::path& root,
                         const XmlParameters& parameters = {});

}  // namespace rayfarm
