#include "common/scene/transform_reader.h"

#include "common/scene/instances.h"

#include <cmath>
#include <string>

#include "common/limits.h"

namespace rayfarm {
using namespace scene_json;  // NOLINT(google-build-using-namespace): the JSON readers

namespace {

WideVec3 wide_of(const Vec3& v) { return wide(v); }

/// 16 numbers, row-major, whose last row is 0 0 0 1.
Transform read_matrix(const Node& n) {
  const Json& values = n.array();
  if (values.size() != 16) {
    n.fail("expected a 4x4 matrix of 16 numbers (row-major), got " + std::to_string(values.size()) +
           " values");
  }
  double m[16];
  for (size_t i = 0; i < 16; ++i) m[i] = read_number(n.child(i));
  if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0) {
    n.fail("the matrix's last row must be 0 0 0 1 (projective transforms are not supported)");
  }
  return Transform({m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11]});
}

Transform read_rotate(const Node& n) {
  n.allow_keys({"axis", "angle"});
  const Node axis_node = n.require("axis");
  const WideVec3 axis = wide_of(read_vec3(axis_node));
  const double len = length(axis);
  if (!(len > 0.0)) axis_node.fail("the rotation axis must not be zero");
  return Transform::rotate({axis.x / len, axis.y / len, axis.z / len},
                           read_number(n.require("angle")));
}

Transform read_look_at(const Node& n) {
  n.allow_keys({"eye", "target", "up"});
  const WideVec3 eye = wide_of(read_point(n.require("eye")));
  const WideVec3 target = wide_of(read_point(n.require("target")));
  const WideVec3 up = n.find("up") ? wide_of(read_vec3(n.require("up"))) : WideVec3{0, 1, 0};
  const WideVec3 forward = target - eye;
  if (length(forward) == 0.0) n.child("target").fail("target equals eye: no direction");
  if (!(length(cross(forward, up)) > 1e-9 * length(forward) * length(up))) {
    n.fail("up is zero or parallel to target - eye");
  }
  return Transform::look_at(eye, target, up);
}

Transform read_scale(const Node& n) {
  const WideVec3 s = n.json().is_number() ? WideVec3{read_number(n), read_number(n), read_number(n)}
                                          : wide_of(read_vec3(n));
  if (s.x == 0.0 || s.y == 0.0 || s.z == 0.0) n.fail("a scale factor must not be zero");
  return Transform::scale(s);
}

/// One operation: an object with exactly one of translate, rotate, scale, look_at, matrix.
Transform read_operation(const Node& n) {
  const Json& object = n.object();
  if (object.size() != 1) {
    n.fail(
        "a transform operation is an object with exactly one key (translate, rotate, scale, "
        "look_at or matrix), got " +
        std::to_string(object.size()));
  }
  const std::string key = object.begin().key();
  const Node value = n.child(key);
  if (key == "translate") return Transform::translate(wide_of(read_point(value)));
  if (key == "rotate") return read_rotate(value);
  if (key == "scale") return read_scale(value);
  if (key == "look_at") return read_look_at(value);
  if (key == "matrix") return read_matrix(value);
  n.fail("unknown transform operation \"" + key +
         "\"; expected translate, rotate, scale, look_at or matrix");
}

/// `p` as a float point of the renderer's range; fails at `where` otherwise.
Vec3 to_point(const WideVec3& p, const Node& where) {
  if (!(std::fabs(p.x) <= kMaxCoordinate && std::fabs(p.y) <= kMaxCoordinate &&
        std::fabs(p.z) <= kMaxCoordinate)) {
    where.fail(
        "the transform moves a point beyond 1e17, the largest coordinate that the "
        "renderer handles");
  }
  return {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
}

}  // namespace

Transform read_transform(const Node& n) {
  Transform t;
  if (n.json().is_object()) {
    t = read_operation(n);
  } else if (n.array().empty() || n.json().front().is_number()) {
    t = read_matrix(n);
  } else {
    for (size_t i = 0; i < n.array().size(); ++i) t = t.then(read_operation(n.child(i)));
  }
  const double det = t.determinant();
  if (!(std::fabs(det) > 0.0) || !std::isfinite(det)) {
    n.fail("the transform is singular (it flattens shapes): determinant " + std::to_string(det));
  }
  return t;
}

void transform_mesh(TriangleMesh& mesh, const Transform& t, const Node& where) {
  if (t.is_identity()) return;
  for (const Vec3& p : mesh.positions) to_point(t.point(wide(p)), where);  // in range?
  mesh = place_mesh(mesh, t);
}

void transform_sphere(Sphere& sphere, const Transform& t, const Node& where) {
  if (t.is_identity()) return;
  const double s = t.uniform_scale();
  if (!(s > 0.0)) {
    where.fail(
        "a sphere's transform must scale all directions alike (it would not stay a "
        "sphere); use a mesh for an ellipsoid");
  }
  sphere.center = to_point(t.point(wide(sphere.center)), where);
  const double radius = sphere.radius * s;
  if (!(radius <= kMaxCoordinate)) where.fail("the transformed radius exceeds 1e17");
  sphere.radius = static_cast<float>(radius);
  auto axis = [&](const Vec3& a) {
    const WideVec3 v = t.vector(wide(a));
    return Vec3(static_cast<float>(v.x / s), static_cast<float>(v.y / s),
                static_cast<float>(v.z / s));
  };
  sphere.axis_x = axis(sphere.axis_x);
  sphere.axis_y = axis(sphere.axis_y);
  sphere.axis_z = axis(sphere.axis_z);
}

}  // namespace rayfarm
