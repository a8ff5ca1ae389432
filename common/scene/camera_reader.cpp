#include "common/scene/camera_reader.h"

#include "common/math/wide.h"

namespace rayfarm {

using namespace scene_json;  // NOLINT(google-build-using-namespace): the JSON readers

namespace {

/// Fails at `n` when the camera has no view direction, or its up lies along it.
void check_view(const Node& n, const Camera& c) {
  const Vec3 forward = c.look_at - c.eye;
  const double distance = length(wide(forward));
  if (distance == 0.0) n.child("look_at").fail("look_at equals eye: no view direction");
  const double up = length(wide(c.up));
  if (up != 0.0 && length(cross(wide(forward), wide(c.up))) > 1e-6 * distance * up) return;
  if (auto given = n.find("up")) given->fail("up is zero or parallel to the view direction");
  n.fail("the default up [0, 1, 0] is parallel to the view direction; give \"up\"");
}

}  // namespace

Camera read_camera(const Node& n) {
  Camera c;
  if (auto type = n.find("type")) {
    const std::string kind = read_string(*type);
    if (kind == "orthographic") {
      c.projection = Camera::Projection::kOrthographic;
    } else if (kind != "perspective") {
      type->fail("unknown camera type " + as_written(type->json()) +
                 "; expected \"perspective\" or \"orthographic\"");
    }
  }
  c.eye = read_point(n.require("eye"));
  c.look_at = read_point(n.require("look_at"));
  if (auto up = n.find("up")) c.up = read_point(*up);
  if (c.projection == Camera::Projection::kOrthographic) {
    n.allow_keys({"type", "eye", "look_at", "up", "view_height"});
    const Node height = n.require("view_height");
    c.view_height = read_length(height);
    if (!(c.view_height > 0.f))
      height.fail("view_height is too small to represent (below ~1e-38)");
    check_view(n, c);
    return c;
  }
  n.allow_keys({"type", "eye", "look_at", "up", "fov_y", "aperture_radius", "focus_distance"});
  const Node fov = n.require("fov_y");
  c.fov_y_deg = read_float(fov);
  if (!(c.fov_y_deg > 0.f && c.fov_y_deg < 180.f)) fov.fail("fov_y must lie in (0, 180) degrees");
  if (auto a = n.find("aperture_radius")) {
    (void)read_non_negative(*a);
    c.aperture_radius = read_coordinate(*a);
  }
  if (auto f = n.find("focus_distance")) c.focus_distance = read_length(*f);
  check_view(n, c);
  return c;
}

}  // namespace rayfarm
