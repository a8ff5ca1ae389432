#include "common/scene/light_reader.h"

#include <cmath>
#include <string>

#include "common/math/transform.h"
#include "common/math/wide.h"
#include "common/scene/scene_files.h"
#include "common/scene/transform_reader.h"
#include "common/util/text.h"

namespace rayfarm {
namespace fs = std::filesystem;
using namespace scene_json;  // NOLINT(google-build-using-namespace): the JSON readers

namespace {

constexpr double kDegree = 3.14159265358979323846 / 180.0;  ///< one degree in radians

/// A direction: three numbers, not all zero, returned unit length.
Vec3 read_direction(const Node& n) {
  const Vec3 d = read_point(n);
  const double len = length(wide(d));
  if (!(len > 0.0)) n.fail("the direction must not be zero");
  return Vec3(float(d.x / len), float(d.y / len), float(d.z / len));
}

/// An angle in degrees in (0, 90]: a cone wider than a hemisphere is not a spot.
float read_half_angle(const Node& n) {
  const float deg = read_float(n);
  if (!(deg > 0.f && deg <= 90.f)) n.fail("expected an angle in (0, 90] degrees");
  return deg;
}

/// A rotation: the environment has no position and no size, so anything else is an error.
std::array<double, 9> read_rotation(const Node& n) {
  const Transform t = read_transform(n);
  std::array<double, 9> r{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r[3 * i + j] = t.at(i, j);
    if (t.at(i, 3) != 0.0) n.fail("an environment's transform must be a rotation (no translation)");
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      // Rows orthonormal: R R^T = I.
      const double d =
          r[3 * i] * r[3 * j] + r[3 * i + 1] * r[3 * j + 1] + r[3 * i + 2] * r[3 * j + 2];
      if (std::fabs(d - (i == j ? 1.0 : 0.0)) > 1e-6)
        n.fail("an environment's transform must be a rotation (no scale or shear)");
    }
  }
  if (!(t.determinant() > 0.0)) n.fail("an environment's transform must be a rotation (no mirror)");
  return r;
}

/// RGB or a single number >= 0, for a scale applied to every channel.
Vec3 read_scale(const Node& n) {
  if (n.json().is_number()) return Vec3(read_non_negative(n));
  return read_radiance(n);
}

PointLight read_point_light(const Node& n) {
  n.allow_keys({"type", "position", "intensity"});
  return {read_point(n.require("position")), read_radiance(n.require("intensity"))};
}

/// The unit axis of a light at `position` from "direction" or "look_at" (one of them required).
Vec3 read_axis(const Node& n, const Vec3& position) {
  const auto direction = n.find("direction");
  const auto look_at = n.find("look_at");
  if (direction && look_at) n.fail("give either \"direction\" or \"look_at\", not both");
  if (direction) return read_direction(*direction);
  if (!look_at) n.fail("missing key \"direction\" (or \"look_at\")");
  const Vec3 target = read_point(*look_at);
  const WideVec3 d = wide(target) - wide(position);
  const double len = length(d);
  if (!(len > 0.0)) look_at->fail("look_at equals position: no direction");
  return Vec3(float(d.x / len), float(d.y / len), float(d.z / len));
}

/// The frame of an image a light casts about `axis`: its y along "up" (default +y, or +z for a
/// light along y) made orthogonal to the axis, its x = axis x y, to the right as seen from the
/// light. With u growing along x and v along y, an image (whose uv origin is its bottom-left
/// corner, the JSON default) lands upright and unmirrored, as a camera there would see it.
SpotImage image_frame(const Node& n, const Vec3& axis) {
  WideVec3 up = std::fabs(axis.y) > 0.999f ? WideVec3{0, 0, 1} : WideVec3{0, 1, 0};
  if (auto u = n.find("up")) up = wide(read_direction(*u));
  const WideVec3 z = wide(axis);
  const double along = up.x * z.x + up.y * z.y + up.z * z.z;
  const WideVec3 y{up.x - along * z.x, up.y - along * z.y, up.z - along * z.z};
  const double len = length(y);
  if (!(len > 1e-6)) n.child("up").fail("up must not be parallel to the light's direction");
  SpotImage image;
  image.y_axis = Vec3(float(y.x / len), float(y.y / len), float(y.z / len));
  image.x_axis = normalize(cross(axis, image.y_axis));
  return image;
}

SpotLight read_spot(const Node& n, const TextureReader& textures) {
  n.allow_keys({"type", "position", "direction", "look_at", "intensity", "cutoff_angle",
                "beam_width", "image", "up"});
  SpotLight s;
  s.position = read_point(n.require("position"));
  s.intensity = read_radiance(n.require("intensity"));
  s.direction = read_axis(n, s.position);
  if (auto c = n.find("cutoff_angle")) s.cutoff_deg = read_half_angle(*c);
  s.beam_width_deg = 0.75f * s.cutoff_deg;
  if (auto b = n.find("beam_width")) {
    s.beam_width_deg = read_half_angle(*b);
    if (s.beam_width_deg > s.cutoff_deg) b->fail("beam_width must not exceed cutoff_angle");
  }
  if (auto image = n.find("image")) {
    if (!(s.cutoff_deg < 90.f)) n.fail("a spot that casts an image needs a cutoff_angle below 90");
    s.image = image_frame(n, s.direction);
    s.image->image = textures.radiance(*image);
    // u = 0.5 + 0.5 x / (z tan(cutoff)) on both axes: the image's square holds the cone.
    s.image->u_scale = s.image->v_scale = float(0.5 / std::tan(double(s.cutoff_deg) * kDegree));
  } else if (n.find("up")) {
    n.child("up").warn("\"up\" orients an image; this spot casts none");
  }
  return s;
}

/// A projector: a camera run backwards, which casts its image through the frustum of a vertical
/// field of view "fov" and an "aspect" ratio (width over height), the image being the irradiance
/// it gives a plane facing it at distance 1 (times "intensity").
SpotLight read_projector(const Node& n, const TextureReader& textures) {
  n.allow_keys(
      {"type", "position", "direction", "look_at", "up", "image", "intensity", "fov", "aspect"});
  SpotLight s;
  s.position = read_point(n.require("position"));
  s.direction = read_axis(n, s.position);
  s.intensity = n.find("intensity") ? read_scale(*n.find("intensity")) : Vec3(1.f);
  const float fov = read_float(n.require("fov"));
  if (!(fov > 0.f && fov < 180.f)) n.child("fov").fail("expected an angle in (0, 180) degrees");
  float aspect = 1.f;
  if (auto a = n.find("aspect")) {
    aspect = read_positive(*a);
    if (!(aspect >= 1e-3f && aspect <= 1e3f)) a->fail("expected an aspect ratio in [0.001, 1000]");
  }
  s.image = image_frame(n, s.direction);
  s.image->image = textures.radiance(n.require("image"));
  s.image->projector = true;
  // u = 0.5 + 0.5 x / (z tan_x), v = 0.5 + 0.5 y / (z tan_y): the image fills the frustum.
  const double tan_y = std::tan(0.5 * double(fov) * kDegree);
  s.image->u_scale = float(0.5 / (tan_y * aspect));
  s.image->v_scale = float(0.5 / tan_y);
  if (!set_projector_cone(s))
    n.fail("a projector narrower than 0.05 degrees (its frustum's corner) is not supported");
  return s;
}

DirectionalLight read_directional(const Node& n) {
  n.allow_keys({"type", "direction", "irradiance"});
  return {read_direction(n.require("direction")), read_radiance(n.require("irradiance"))};
}

EnvironmentMap read_environment(const Node& n, const fs::path& folder, SceneImages images) {
  n.allow_keys({"type", "file", "scale", "transform"});
  EnvironmentMap env;
  const Node file = n.require("file");
  std::string why;
  const auto relative = resolve_scene_path(fs::path(), read_string(file), &why);
  if (!relative) file.fail(as_written(file.json()) + ": " + why);
  env.file = *relative;
  if (images == SceneImages::kSkip) {
    if (auto s = n.find("scale")) env.scale = read_scale(*s);
    if (auto t = n.find("transform")) env.rotation = read_rotation(*t);
    return env;
  }
  // Kept until its radiances are checked, whatever `images` says.
  env.image = decode_scene_image(file, folder, env.file, SceneImages::kKeep, "environment image");
  if (!(env.image->width > 0 && env.image->height > 0)) file.fail("the image is empty");
  if (auto s = n.find("scale")) env.scale = read_scale(*s);
  check_environment_radiance(file, env.file, *env.image, env.scale);
  if (images == SceneImages::kCheckOnly) env.image.reset();
  if (auto t = n.find("transform")) env.rotation = read_rotation(*t);
  return env;
}

EnvironmentMap read_constant(const Node& n) {
  n.allow_keys({"type", "radiance"});
  EnvironmentMap env;
  env.scale = read_radiance(n.require("radiance"));
  return env;
}

}  // namespace

bool set_projector_cone(SpotLight& projector) {
  const double tan_x = 0.5 / std::fabs(double(projector.image->u_scale)),
               tan_y = 0.5 / std::fabs(double(projector.image->v_scale));
  const double corner = std::atan(std::sqrt(tan_x * tan_x + tan_y * tan_y)) / kDegree;
  if (!(corner >= kMinProjectorDegrees)) return false;
  projector.cutoff_deg = projector.beam_width_deg = static_cast<float>(corner);
  return true;
}

void check_environment_radiance(const Node& file_node, const fs::path& file,
                                const DecodedImage& image, const Vec3& scale) {
  if (!image.is_float()) return;  // 8-bit samples are at most 1
  const uint32_t channels = image.channels;
  const uint32_t colours = channels >= 3 ? 3 : 1;
  uint64_t unusable = 0;
  for (uint32_t y = 0; y < image.height; ++y) {
    for (uint32_t x = 0; x < image.width; ++x) {
      const float* p = &image.floats[(size_t{y} * image.width + x) * channels];
      float c[3];
      for (uint32_t k = 0; k < 3; ++k) {
        const float v = p[colours == 3 ? k : 0];
        if (k < colours && !(std::isfinite(v) && v >= 0.f)) ++unusable;
        c[k] = std::isfinite(v) && v > 0.f ? v : 0.f;
      }
      const float lum = luminance(Vec3(c[0], c[1], c[2]) * scale);
      if (!std::isfinite(lum)) {
        file_node.fail(printable(file.string()) + ": the texel at (" + std::to_string(x) + ", " +
                       std::to_string(y) + ") times the scale is a radiance beyond the float " +
                       "range (3.4e38): the environment's power would be infinite");
      }
    }
  }
  if (unusable > 0) {
    file_node.warn(printable(file.string()) + ": " + std::to_string(unusable) +
                   " sample(s) are negative, infinite or NaN and are taken as black");
  }
}

void read_lights(const Node& n, const fs::path& folder, SceneImages images,
                 const TextureReader& textures, Scene& scene) {
  std::string first_environment;
  for (size_t i = 0; i < n.array().size(); ++i) {
    const Node light = n.child(i);
    const Node type = light.require("type");
    const std::string kind = read_string(type);
    if (kind == "point") {
      scene.point_lights.push_back(read_point_light(light));
    } else if (kind == "spot") {
      scene.spot_lights.push_back(read_spot(light, textures));
    } else if (kind == "projector") {
      scene.spot_lights.push_back(read_projector(light, textures));
    } else if (kind == "directional") {
      scene.directional_lights.push_back(read_directional(light));
    } else if (kind == "environment" || kind == "constant") {
      if (scene.environment) {
        light.fail("a scene has at most one environment (\"environment\" or \"constant\"); " +
                   first_environment + " is one already");
      }
      first_environment = "lights[" + std::to_string(i) + "]";
      scene.environment =
          kind == "constant" ? read_constant(light) : read_environment(light, folder, images);
      if (!scene.environment->file.empty()) {
        bool known = false;
        for (const fs::path& r : scene.referenced) known = known || r == scene.environment->file;
        if (!known) scene.referenced.push_back(scene.environment->file);
      }
    } else {
      type.fail("unknown light type " + as_written(type.json()) +
                "; expected one of point, spot, projector, directional, environment, constant");
    }
  }
}

}  // namespace rayfarm
