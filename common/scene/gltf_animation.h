#pragma once
// glTF 2.0 animations (docs/gltf.md, "Animation"): the node translations, rotations and scales
// that a file's animations key, set to their values at a time, before the nodes are read. Every
// animation of the file plays at once, from time 0; a camera node moves the camera with it.
#include <tiny_gltf.h>

#include "common/scene/gltf_accessors.h"

namespace rayfarm::gltf {

/// The time of the last key of any channel of any animation, in seconds; 0 when the file has no
/// animation. Throws SceneError naming the place of a malformed animation.
double animation_duration(const Source& src);

/// Sets every animated node property of `model` (the model `src` reads) to its value at `seconds`:
/// before a channel's first key its first value, after its last key its last. Channels of
/// morph-target weights are ignored with a warning. Throws SceneError naming the place of a
/// malformed animation (sampler, accessor, interpolation, a target node with a matrix).
void apply_animations(const Source& src, tinygltf::Model& model, double seconds);

}  // namespace rayfarm::gltf
