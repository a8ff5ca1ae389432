#pragma once
// The node hierarchy of a glTF scene: each node's world transform, and the meshes, camera and
// KHR_lights_punctual lights it places. Internal to the glTF loader.
#include "common/scene/gltf_materials.h"
#include "common/scene/gltf_options.h"

namespace rayfarm::gltf {

/// Walks the default scene (or, without scenes, every root node), adding meshes and lights to
/// `scene` and setting its camera when one is found.
GltfResult read_nodes(const Source& src, Materials& materials, const GltfOptions& options,
                      Scene& scene);

}  // namespace rayfarm::gltf
