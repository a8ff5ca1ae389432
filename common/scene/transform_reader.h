#pragma once
// Shape transforms in the JSON format (docs/scene-format.md, "Transforms"): reading them, and
// applying them to meshes and spheres once, at load time.
#include "common/math/transform.h"
#include "common/scene/json_reader.h"
#include "common/scene/scene.h"

namespace rayfarm {

/// A shape's "transform": a 4x4 matrix (16 numbers, row-major), one operation object, or an
/// array of operation objects applied to the shape in the order listed.
Transform read_transform(const scene_json::Node& n);

/// Moves a mesh's positions and normals by `t` (winding reversed when `t` mirrors, so that front
/// faces stay front faces). Fails at `where` when a point leaves the renderer's range.
void transform_mesh(TriangleMesh& mesh, const Transform& t, const scene_json::Node& where);

/// Moves a sphere by `t`, which must scale uniformly (a sphere stays a sphere).
void transform_sphere(Sphere& sphere, const Transform& t, const scene_json::Node& where);

}  // namespace rayfarm
