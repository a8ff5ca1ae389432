#pragma once
// Thin-lens perspective and orthographic cameras. Right-handed: the image's right is forward x up;
// row 0 is the top.
#include <cmath>
#include <vector>

#include "common/math/wide.h"
#include "common/scene/scene.h"
#include "renderer/embree/bvh.h"
#include "renderer/motion_blend.h"

namespace rayfarm {

class CameraModel {
 public:
  CameraModel(const Camera& c, FilmSize film) {
    eye_ = c.eye;
    // Double precision: the parser accepts any up and any distance from eye to look_at, from
    // 1e-30 to 1e17; in float, up = [0, 1e-30, 0] gave NaN rays.
    forward_ = normalize_wide(Vec3(float(double(c.look_at.x) - c.eye.x),
                                   float(double(c.look_at.y) - c.eye.y),
                                   float(double(c.look_at.z) - c.eye.z)));
    right_ = normalize_wide(cross(forward_, normalize_wide(c.up)));
    up_ = cross(right_, forward_);
    tan_half_ = std::tan(0.5f * c.fov_y_deg * kPi / 180.f);
    if (c.full_width > 0 && c.full_height > 0) {  // a crop of a larger image
      film = {c.full_width, c.full_height};
      crop_x_ = static_cast<float>(c.crop_x);
      crop_y_ = static_cast<float>(c.crop_y);
    }
    aspect_ = static_cast<float>(film.width) / static_cast<float>(film.height);
    inv_w_ = 1.f / static_cast<float>(film.width);
    inv_h_ = 1.f / static_cast<float>(film.height);
    lens_ = c.aperture_radius;
    focus_ = c.focus_distance > 0.f ? c.focus_distance : length(c.look_at - c.eye);
    ortho_ = c.projection == Camera::Projection::kOrthographic;
    ortho_half_ = 0.5f * c.view_height;
  }

  /// Ray through film position (x + jx, y + jy) in pixels; (lu, lv) pick the lens point.
  Ray generate(float fx, float fy, float lu, float lv) const {
    fx += crop_x_;
    fy += crop_y_;
    const float sx = (2.f * fx * inv_w_ - 1.f) * tan_half_ * aspect_;
    const float sy = (1.f - 2.f * fy * inv_h_) * tan_half_;
    if (ortho_) {
      // Parallel rays from the film's points on the plane through eye; the lens plays no part.
      const float ox = (2.f * fx * inv_w_ - 1.f) * ortho_half_ * aspect_;
      const float oy = (1.f - 2.f * fy * inv_h_) * ortho_half_;
      return Ray{eye_ + right_ * ox + up_ * oy, forward_};
    }
    Vec3 dir = forward_ + right_ * sx + up_ * sy;  // forward component 1: a point at depth 1
    Ray ray;
    ray.org = eye_;
    if (lens_ > 0.f) {
      const float r = lens_ * std::sqrt(lu), phi = 2.f * kPi * lv;
      const Vec3 lens_point = right_ * (r * std::cos(phi)) + up_ * (r * std::sin(phi));
      ray.org = eye_ + lens_point;
      dir = dir * focus_ - lens_point;
    }
    ray.dir = normalize_wide(dir);
    return ray;
  }

 private:
  Vec3 eye_, forward_, right_, up_;
  float tan_half_ = 1.f, aspect_ = 1.f, inv_w_ = 1.f, inv_h_ = 1.f, lens_ = 0.f, focus_ = 1.f;
  bool ortho_ = false;
  float ortho_half_ = 0.f;             // orthographic: half the view height
  float crop_x_ = 0.f, crop_y_ = 0.f;  // the film's offset in the whole image
};

/// A camera that moves within the shutter: one model per pose (common/scene/motion.h), the ray
/// at a time blended between the two poses around it (origin and direction, linearly).
class MovingCamera {
 public:
  /// `still` carries what does not move (projection, crop); `poses` the animated values.
  MovingCamera(const Camera& still, const std::vector<Camera>& poses, FilmSize film) {
    for (const Camera& p : poses) {
      Camera c = still;
      c.eye = p.eye;
      c.look_at = p.look_at;
      c.up = p.up;
      c.fov_y_deg = p.fov_y_deg;
      c.aperture_radius = p.aperture_radius;
      c.focus_distance = p.focus_distance;
      c.view_height = p.view_height;
      poses_.emplace_back(c, film);
    }
  }

  bool empty() const { return poses_.empty(); }

  /// CameraModel::generate() at `time` in [0, 1].
  Ray generate(float fx, float fy, float lu, float lv, float time) const {
    const PoseBlend b = pose_blend(static_cast<uint32_t>(poses_.size()), time);
    const Ray r0 = poses_[b.i].generate(fx, fy, lu, lv);
    const Ray r1 = poses_[b.i + 1].generate(fx, fy, lu, lv);
    Ray ray;
    ray.org = blend(r0.org, r1.org, b.f);
    ray.dir = normalize_wide(blend(r0.dir, r1.dir, b.f));
    ray.time = time;
    return ray;
  }

 private:
  std::vector<CameraModel> poses_;
};

}  // namespace rayfarm
