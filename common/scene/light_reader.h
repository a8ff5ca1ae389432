#pragma once
// The "lights" section of the JSON format (docs/scene-format.md, "Lights"): point, spot (with or
// without an image), projector and directional lights, and the one environment (an image or a
// constant) that a scene may have.
#include <filesystem>

#include "common/scene/json_reader.h"
#include "common/scene/scene.h"
#include "common/scene/texture_reader.h"

namespace rayfarm {

/// Reads the "lights" array into `scene`; an environment's image (relative to `folder`) is
/// decoded here, kept or only checked as `images` says, and added to scene.referenced. The images
/// spots and projectors cast name the scene's textures (`textures`).
void read_lights(const scene_json::Node& n, const std::filesystem::path& folder, SceneImages images,
                 const TextureReader& textures, Scene& scene);

/// The narrowest projector the scene formats take, the angle of its frustum's corner from its
/// axis in degrees: a narrower cone rounds away in the light's single-precision bounds.
inline constexpr double kMinProjectorDegrees = 0.05;

/// Sets a projector's cone (its cutoff and beam width) through the corners of the frustum its
/// image's uv scales describe (u = 0.5 + u_scale x / z: the image spans |x / z| <= 0.5 /
/// |u_scale|): at full intensity within, for the light tree. False when it is narrower than
/// kMinProjectorDegrees.
bool set_projector_cone(SpotLight& projector);

/// Fails at `file_node` when a texel of the environment image times `scale` has a luminance
/// beyond the float range (the worker's light would have infinite power), and warns about
/// samples it takes as black (negative, infinite, NaN).
void check_environment_radiance(const scene_json::Node& file_node,
                                const std::filesystem::path& file, const DecodedImage& image,
                                const Vec3& scale);

}  // namespace rayfarm
