#pragma once
// Shading beyond the BSDF at a hit: the normal and bump maps that perturb the shading normal, and
// the frame that follows the tangent for anisotropic BSDFs. Called only for scenes whose
// materials need it (SceneData::uses_surface()).
#include "common/math/vec3.h"
#include "renderer/embree/bvh.h"
#include "renderer/scene_data.h"

namespace rayfarm {

/// The shading frame of `hit`, whose ns this replaces by its material's normal- or bump-mapped
/// normal (kept on n's side, so the integrator's same-side checks keep light from leaking).
Frame shade_surface(const SceneData& data, const RayHit& rh, SurfaceHit& hit);

/// Orthonormal frame around unit `n` whose first axis is `tangent` made orthogonal to n; the
/// arbitrary Frame(n) when the tangent is (nearly) parallel to n or zero.
Frame tangent_aligned_frame(const Vec3& n, const Vec3& tangent);

/// ns tilted by the tangent-space normal `m` (x along tangent, y along bitangent, z along ns).
/// ns itself, bit for bit, when m has no tilt.
Vec3 apply_tangent_normal(const Vec3& ns, const TangentFrame& tf, const Vec3& m);

/// The normal of the surface displaced by the height h along ns, from the height's derivatives.
Vec3 bumped_normal(const Vec3& ns, const TangentFrame& tf, float dh_du, float dh_dv);

}  // namespace rayfarm
