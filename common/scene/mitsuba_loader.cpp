// A Mitsuba 3 scene, top down (docs/mitsuba.md): the integrator and the sensor first (the caller
// checks the film and the render settings before any mesh is read), then the emitters and shapes.
#include "common/scene/mitsuba_loader.h"

#include <algorithm>
#include <cmath>

#include "common/limits.h"
#include "common/scene/json_reader.h"
#include "common/scene/light_reader.h"
#include "common/scene/mitsuba_reader.h"
#include "common/util/text.h"

namespace rayfarm {
namespace fs = std::filesystem;

namespace mitsuba {
namespace {

constexpr double kPi = 3.14159265358979323846;
double degrees(double radians) { return radians * 180.0 / kPi; }
double radians(double degrees) { return degrees * kPi / 180.0; }
Vec3 to_vec(const WideVec3& v) { return {float(v.x), float(v.y), float(v.z)}; }
WideVec3 unit(const WideVec3& v) {
  const double l = length(v);
  return {v.x / l, v.y / l, v.z / l};
}

void collect_ids(const XmlElement& e, std::map<std::string, const XmlElement*>& ids) {
  for (const XmlElement& c : e.children) {
    if (const std::string* id = c.find("id"); id != nullptr && c.tag != "ref") {
      if (!ids.emplace(*id, &c).second)
        c.fail("the id \"" + printable(*id, 64) + "\" is given twice");
    }
    collect_ids(c, ids);
  }
}

/// Mitsuba's depth counts path segments (1: emitters seen directly, 2: direct light); rayfarm's
/// counts scattering vertices (0 and 1 for those): one less. -1 is unlimited.
void read_integrator(Context& ctx, const XmlElement& e, RenderSettings& r, int nesting = 0) {
  Props p(e, ctx);
  const std::string type = type_of(e);
  if (type == "moment") {
    if (nesting > 0) e.fail("a moment integrator inside another is not supported");
    const auto inner = p.plugins("integrator");
    if (inner.size() != 1) e.fail("a moment integrator wraps one integrator");
    p.finish();
    read_integrator(ctx, *inner[0], r, nesting + 1);
    return;
  }
  r.integrator = IntegratorType::kMis;
  if (type == "direct") {
    r.max_depth = 1;
    p.finish({"emitter_samples", "bsdf_samples", "shading_samples"});
    return;
  }
  // Integrators that estimate the path tracer's image another way: rendered by rayfarm's path
  // tracer, with their depths, and a warning.
  const bool same_image = type == "ptracer" || type == "bdpt" || type == "prb" ||
                          type == "prb_basic" || type == "prbvolpath";
  if (type != "path" && type != "volpath" && type != "volpathmis" && !same_image) {
    e.fail("the integrator \"" + printable(type, 40) +
           "\" is not supported (path, volpath, volpathmis and direct are; ptracer, bdpt and prb "
           "are rendered by the path tracer)");
  }
  const int64_t depth = p.integer("max_depth", -1, -1, INT32_MAX);
  // Mitsuba's roulette acts on the throughput from its rr_depth-th vertex on (counted from 1).
  const int64_t rr_depth = p.integer("rr_depth", 5, 1, INT32_MAX);
  if (p.boolean("hide_emitters", false))
    p.find("hide_emitters")->fail("hide_emitters is not supported");
  p.finish({"samples_per_pass"});
  if (same_image) {
    ctx.warn_once(
        "integrator", e,
        "rendered by rayfarm's path tracer, which converges to the same image as \"" + type + "\"");
  }
  if (depth == 0) e.fail("max_depth 0 renders nothing");
  r.max_depth = depth == -1 || depth - 1 > int64_t{kMaxDepth} ? kUnlimitedDepth
                                                              : static_cast<uint32_t>(depth - 1);
  r.roulette = RouletteType::kThroughput;
  r.roulette_depth = static_cast<uint32_t>(std::min<int64_t>(rr_depth - 1, kMaxRouletteDepth));
}

/// The horizontal field of view Mitsuba derives from fov / fov_axis or focal_length.
double x_fov(Props& p, double aspect) {
  if (p.has("fov") && p.has("focal_length")) p.element().fail("give fov or focal_length, not both");
  double fov = 0.0;
  std::string axis;
  if (p.has("fov")) {
    fov = p.number("fov", 0.0);
    axis = p.string("fov_axis", "x");
    if (axis == "smaller") axis = aspect > 1 ? "y" : "x";
    if (axis == "larger") axis = aspect > 1 ? "x" : "y";
  } else {
    const XmlElement* given = p.find("focal_length");
    std::string f = given != nullptr ? value_of(*given) : "50mm";
    if (f.size() > 2 && f.compare(f.size() - 2, 2, "mm") == 0) f.resize(f.size() - 2);
    const std::vector<double> mm = parse_numbers(given != nullptr ? *given : p.element(), f);
    if (mm.size() != 1 || !(mm[0] > 0.0))
      p.element().fail("focal_length must be a positive length in mm");
    fov = 2.0 * degrees(std::atan(std::sqrt(36.0 * 36.0 + 24.0 * 24.0) / (2.0 * mm[0])));
    axis = "diagonal";
  }
  if (!(fov > 0.0 && fov < 180.0))
    p.element().fail("the field of view must lie in (0, 180) degrees");
  if (axis == "x") return fov;
  if (axis == "y") return degrees(2.0 * std::atan(std::tan(0.5 * radians(fov)) * aspect));
  if (axis == "diagonal") {
    const double diagonal = 2.0 * std::tan(0.5 * radians(fov));
    return degrees(2.0 * std::atan(0.5 * diagonal / std::sqrt(1.0 + 1.0 / (aspect * aspect))));
  }
  p.find("fov_axis")->fail("fov_axis must be x, y, diagonal, smaller or larger");
}

/// Mitsuba's scalar variants evaluate a filter from a table of this many steps
/// (MI_FILTER_RESOLUTION): its references are rendered with that filter.
constexpr uint32_t kMitsubaFilterSteps = 31;

/// An <rfilter> with Mitsuba's defaults; null: the film names none (Mitsuba's Gaussian).
PixelFilter read_rfilter(Context& ctx, const XmlElement* e) {
  PixelFilter f;
  f.type = FilterType::kGaussian;
  f.radius = 4.f * f.stddev;
  f.steps = kMitsubaFilterSteps;
  if (e == nullptr) return f;
  Props p(*e, ctx);
  const std::string type = type_of(*e);
  if (type == "box") {
    f = PixelFilter{};  // each pixel's own samples, as Mitsuba's box
  } else if (type == "tent") {
    f.type = FilterType::kTent;
    f.radius = static_cast<float>(p.number("radius", 1.0));
    if (!(f.radius >= kMinFilterRadius && f.radius <= kMaxFilterRadius))
      e->fail("a tent filter's radius must lie in [0.001, 8] pixels");
  } else if (type == "gaussian") {
    f.stddev = static_cast<float>(p.number("stddev", 0.5));
    if (!(f.stddev >= kMinFilterRadius / 4.f && f.stddev <= kMaxFilterRadius / 4.f))
      e->fail("a gaussian filter's stddev must lie in [0.00025, 2] pixels");
    f.radius = 4.f * f.stddev;
  } else if (type == "mitchell" || type == "catmullrom") {
    f.type = FilterType::kMitchell;
    f.radius = 2.f;
    f.b = type == "catmullrom" ? 0.f : static_cast<float>(p.number("B", 1.0 / 3.0));
    f.c = type == "catmullrom" ? 0.5f : static_cast<float>(p.number("C", 1.0 / 3.0));
    if (!(f.b >= 0.f && f.b <= 1.f && f.c >= 0.f && f.c <= 1.f))
      e->fail("a mitchell filter's B and C must lie in [0, 1]");
  } else if (type == "lanczos") {
    f.type = FilterType::kLanczos;
    f.radius = static_cast<float>(p.integer("lobes", 3, 1, int64_t(kMaxFilterRadius)));
  } else {
    e->fail("the reconstruction filter \"" + printable(type, 32) +
            "\" is not supported (box, tent, gaussian, mitchell, catmullrom and lanczos are)");
  }
  p.finish();
  return f;
}

void read_film(Context& ctx, const XmlElement& e, Camera& camera) {
  Props p(e, ctx);
  if (type_of(e) != "hdrfilm")
    e.fail("the film \"" + printable(type_of(e), 32) + "\" is not supported (hdrfilm is)");
  const int64_t w = p.integer("width", 768, 1, kMaxFilmSide),
                h = p.integer("height", 576, 1, kMaxFilmSide);
  const int64_t cx = p.integer("crop_offset_x", 0, 0, w - 1),
                cy = p.integer("crop_offset_y", 0, 0, h - 1);
  const int64_t cw = p.integer("crop_width", w - cx, 1, w - cx),
                ch = p.integer("crop_height", h - cy, 1, h - cy);
  if (cw * ch > kMaxFilmPixels) e.fail("the film has more pixels than the limit of 2^26");
  const auto filters = p.plugins("rfilter");
  if (filters.size() > 1) e.fail("a film has one rfilter");
  ctx.scene.filter = filters.empty() ? read_rfilter(ctx, nullptr) : read_rfilter(ctx, filters[0]);
  ctx.scene.filter.sample_border = p.boolean("sample_border", false);
  p.finish({"pixel_format", "component_format", "file_format", "banner", "high_quality_edges",
            "compensate"});
  ctx.scene.film = {static_cast<uint32_t>(cw), static_cast<uint32_t>(ch)};
  if (cw != w || ch != h) {
    camera.full_width = static_cast<uint32_t>(w);
    camera.full_height = static_cast<uint32_t>(h);
    camera.crop_x = static_cast<uint32_t>(cx);
    camera.crop_y = static_cast<uint32_t>(cy);
  }
}

void read_sensor(Context& ctx, const XmlElement& e) {
  Props p(e, ctx);
  const std::string type = type_of(e);
  if (type != "perspective" && type != "thinlens" && type != "orthographic")
    e.fail("the sensor \"" + printable(type, 32) +
           "\" is not supported (perspective, thinlens and orthographic are)");
  Camera& c = ctx.scene.camera;
  const auto films = p.plugins("film");
  if (films.size() > 1) e.fail("a sensor has one film");
  XmlElement default_film{"film", {{"type", "hdrfilm"}}, {}, e.file, e.line};
  read_film(ctx, films.empty() ? default_film : *films[0], c);
  const auto samplers = p.plugins("sampler");
  if (samplers.size() > 1) e.fail("a sensor has one sampler");
  ctx.scene.render.spp = 4;  // Mitsuba's default sample_count
  if (!samplers.empty()) {
    Props s(*samplers[0], ctx);
    ctx.scene.render.spp = static_cast<uint32_t>(s.integer("sample_count", 4, 1, kMaxSpp));
    s.finish({"seed", "jitter"});
    if (type_of(*samplers[0]) != "independent") {
      ctx.warn_once("sampler", *samplers[0],
                    "rayfarm's own sampler is used (the image converges to the same)");
    }
  }
  const Transform t = p.transform("to_world");
  const WideVec3 eye = t.point({0, 0, 0}), x = t.vector({1, 0, 0}), y = t.vector({0, 1, 0}),
                 z = t.vector({0, 0, 1});
  if (t.determinant() < 0.0) e.fail("a mirroring to_world (it flips the image) is not supported");
  const double aspect = c.full_width > 0 ? double(c.full_width) / c.full_height
                                         : double(ctx.scene.film.width) / ctx.scene.film.height;
  c.eye = to_vec(eye);
  c.up = to_vec(unit(y));
  const WideVec3 forward = unit(z);
  c.look_at = to_vec({eye.x + forward.x, eye.y + forward.y, eye.z + forward.z});
  if (type == "orthographic") {
    const double sx = length(x), sy = length(y);
    if (std::fabs(sx - sy) > 1e-6 * sx)
      e.fail("an orthographic sensor's to_world must scale x and y alike");
    c.projection = Camera::Projection::kOrthographic;
    c.view_height = static_cast<float>(2.0 * sy / aspect);
    p.finish({"near_clip", "far_clip"});
    return;
  }
  if (t.uniform_scale() == 0.0 || std::fabs(t.uniform_scale() - 1.0) > 1e-5)
    e.fail("scale factors in a camera's to_world are not allowed");
  c.fov_y_deg = static_cast<float>(
      degrees(2.0 * std::atan(std::tan(0.5 * radians(x_fov(p, aspect))) / aspect)));
  for (const char* k : {"principal_point_offset_x", "principal_point_offset_y"}) {
    if (p.number(k, 0.0) != 0.0) p.find(k)->fail("an off-centre principal point is not supported");
  }
  if (type == "thinlens") {
    c.aperture_radius = static_cast<float>(p.number("aperture_radius", 0.0));
    if (!(c.aperture_radius >= 0.f)) p.find("aperture_radius")->fail("must not be negative");
    c.focus_distance = static_cast<float>(p.number("focus_distance", 0.0));
    if (!(c.focus_distance > 0.f)) e.fail("a thinlens sensor needs a positive focus_distance");
  }
  p.finish({"near_clip", "far_clip", "shutter_open", "shutter_close", "srf"});
}

}  // namespace

/// An image a spot or projector casts: `colour` (a texture in Mitsuba's own uv, or a constant)
/// on the light's frame, which to_world must place without scaling or mirroring.
SpotImage light_image(Context& ctx, const XmlElement& e, const Transform& t, const Colour& colour,
                      double u_scale, double v_scale) {
  if (std::fabs(t.uniform_scale() - 1.0) > 1e-5 || !(t.determinant() > 0.0))
    e.fail("the to_world of a light that casts an image must be a rotation and a translation");
  SpotImage image;
  image.image = textured_rgb(ctx, colour, UvKind::kNative);
  image.x_axis = to_vec(unit(t.vector({1, 0, 0})));
  image.y_axis = to_vec(unit(t.vector({0, 1, 0})));
  image.u_scale = static_cast<float>(u_scale);
  image.v_scale = static_cast<float>(v_scale);
  return image;
}

/// Width over height of a texture's image (1 for a procedural one, as Mitsuba's resolution()).
double image_aspect(Context& ctx, const XmlElement& texture) {
  if (type_of(texture) != "bitmap") return 1.0;
  const int32_t index = texture_of(ctx, texture, UvKind::kNative, true);
  const TextureDesc& desc = ctx.scene.textures[static_cast<size_t>(index)];
  if (auto it = ctx.aspects.find(desc.file); it != ctx.aspects.end()) return it->second;
  std::shared_ptr<const DecodedImage> image = desc.image;
  if (image == nullptr) {  // loaded only to be checked: decoded once more, for its size only
    const At at(texture, ctx.scene, "filename");
    image = decode_scene_image(at.node, ctx.files.scene_dir, desc.file, SceneImages::kKeep,
                               "texture image");
  }
  const double aspect = double(image->width) / double(image->height);
  ctx.aspects[desc.file] = aspect;
  return aspect;
}

void read_emitter(Context& ctx, const XmlElement& e) {
  Props p(e, ctx);
  const std::string type = type_of(e);
  Scene& scene = ctx.scene;
  const Transform t = p.transform("to_world");
  if (type == "point") {
    PointLight l;
    const auto position = p.point("position");
    l.position = to_vec(position ? *position : t.point({0, 0, 0}));
    l.intensity = p.colour("intensity", Vec3(1.f), SpectrumRole::emission).value;
    p.finish();
    scene.point_lights.push_back(l);
  } else if (type == "spot") {
    SpotLight l;
    l.position = to_vec(t.point({0, 0, 0}));
    l.direction = to_vec(unit(t.vector({0, 0, 1})));
    l.intensity = p.colour("intensity", Vec3(1.f), SpectrumRole::emission).value;
    l.cutoff_deg = static_cast<float>(p.number("cutoff_angle", 20.0));
    l.beam_width_deg = static_cast<float>(p.number("beam_width", l.cutoff_deg * 0.75));
    const bool textured = p.has("texture");
    const Colour texture = p.colour("texture", Vec3(1.f), SpectrumRole::unbounded);
    p.finish();
    if (!(l.cutoff_deg > 0.f && l.cutoff_deg <= 90.f))
      e.fail("cutoff_angle must lie in (0, 90] degrees");
    if (!(l.beam_width_deg >= 0.f && l.beam_width_deg <= l.cutoff_deg))
      e.fail("beam_width must lie in [0, cutoff_angle]");
    if (textured && texture.texture == nullptr)
      p.find("texture")->fail("a spot's texture must be a texture (Mitsuba refuses a constant)");
    if (textured && !(l.cutoff_deg < 90.f))
      e.fail("a spot that casts a texture needs a cutoff_angle below 90 degrees");
    if (textured) {
      // Mitsuba's uv: 0.5 + 0.5 x / (z tan(cutoff)) on both axes of the light's frame.
      const double scale = 0.5 / std::tan(radians(l.cutoff_deg));
      l.image = light_image(ctx, e, t, texture, scale, scale);
    }
    scene.spot_lights.push_back(l);
  } else if (type == "projector") {
    // A perspective camera run backwards: the irradiance image (a texture, or a constant) lights
    // the scene through the camera's frustum; intensity pi x scale x white (Mitsuba's D65) over
    // cos^3, so that the image over pi is the radiance of a white diffuse plane facing it at
    // distance 1 (image_spot_light.h).
    const Colour irradiance = p.colour("irradiance", Vec3(1.f), SpectrumRole::unbounded);
    if (irradiance.texture == nullptr && !(min_component(irradiance.value) >= 0.f))
      p.find("irradiance")->fail("a projector's irradiance must not be negative");
    const double scale = p.number("scale", 1.0);
    if (!(scale >= 0.0)) e.fail("scale must not be negative");
    const double aspect =
        irradiance.texture != nullptr ? image_aspect(ctx, *irradiance.texture) : 1.0;
    const double tan_x = std::tan(0.5 * radians(x_fov(p, aspect)));
    p.finish();
    SpotLight l;
    l.position = to_vec(t.point({0, 0, 0}));
    l.direction = to_vec(unit(t.vector({0, 0, 1})));
    l.intensity = static_cast<float>(kPi * scale) * kEmitterWhite;
    // Mitsuba's sample space: u = 0.5 - 0.5 x / (z tan_x), v = 0.5 - 0.5 aspect y / (z tan_x).
    l.image = light_image(ctx, e, t, irradiance, -0.5 / tan_x, -0.5 * aspect / tan_x);
    l.image->projector = true;
    if (!set_projector_cone(l)) e.fail("a projector narrower than 0.05 degrees is not supported");
    scene.spot_lights.push_back(l);
  } else if (type == "directional") {
    DirectionalLight l;
    const auto direction = p.point("direction");
    const WideVec3 d = direction ? *direction : t.vector({0, 0, 1});
    if (!(length(d) > 0.0)) e.fail("the direction must not be zero");
    l.direction = to_vec(unit(d));
    l.irradiance = p.colour("irradiance", Vec3(1.f), SpectrumRole::emission).value;
    p.finish();
    scene.directional_lights.push_back(l);
  } else if (type == "constant" || type == "envmap") {
    if (scene.environment) e.fail("a scene has at most one constant or envmap emitter");
    EnvironmentMap env;
    if (type == "constant") {
      const Colour c = p.colour("radiance", Vec3(1.f), SpectrumRole::emission);
      if (c.texture != nullptr) e.fail("a textured constant emitter is not supported");
      env.scale = c.value;
    } else {
      const XmlElement* file = p.find("filename");
      if (file == nullptr) e.fail("an envmap needs a filename");
      env.file = resolve_mitsuba_file(ctx.files, *file, value_of(*file));
      env.scale = Vec3(static_cast<float>(p.number("scale", 1.0)));
      env.bilinear = true;  // as Mitsuba reads its envmap
      if (!(env.scale.x >= 0.f)) e.fail("scale must not be negative");
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) env.rotation[3 * i + j] = t.at(i, j);
      }
      if (t.at(0, 3) != 0.0 || t.at(1, 3) != 0.0 || t.at(2, 3) != 0.0 ||
          std::fabs(t.uniform_scale() - 1.0) > 1e-5 || !(t.determinant() > 0.0))
        e.fail("an envmap's to_world must be a rotation");
      const At at(e, scene, "filename");
      env.image = decode_scene_image(at.node, ctx.files.scene_dir, env.file, SceneImages::kKeep,
                                     "environment image");
      check_environment_radiance(at.node, env.file, *env.image, env.scale);
      if (ctx.images != SceneImages::kKeep) env.image.reset();
    }
    p.finish();
    scene.environment = std::move(env);
  } else if (type == "area") {
    e.fail("an area emitter belongs inside a <shape>");
  } else {
    e.fail("the emitter \"" + printable(type, 40) +
           "\" is not supported (docs/mitsuba.md lists the emitters rayfarm reads)");
  }
}

}  // namespace mitsuba

Scene load_mitsuba_scene(const fs::path& file, const SceneCheck& check, SceneImages images,
                         const fs::path& root, const XmlParameters& parameters) {
  using namespace mitsuba;  // NOLINT(google-build-using-namespace): the reader's parts
  XmlScene xml = read_mitsuba_xml(file, root, parameters);
  Scene scene;
  scene.source = file;
  Context ctx{scene, xml.files, images};
  collect_ids(xml.root, ctx.ids);
  const XmlElement* sensor = nullptr;
  const XmlElement* integrator = nullptr;
  for (const XmlElement& c : xml.root.children) {
    const XmlElement*& slot = c.tag == "sensor"       ? sensor
                              : c.tag == "integrator" ? integrator
                                                      : sensor;
    if (c.tag != "sensor" && c.tag != "integrator") continue;
    if (slot != nullptr) c.fail("the scene has more than one <" + c.tag + ">; rayfarm renders one");
    slot = &c;
  }
  if (sensor == nullptr) xml.root.fail("the scene has no <sensor>");
  scene.render.max_depth = kUnlimitedDepth;  // Mitsuba's path integrator is unlimited by default
  if (integrator != nullptr) read_integrator(ctx, *integrator, scene.render);
  read_sensor(ctx, *sensor);
  if (check) {
    if (auto refusal = check(scene.film, scene.render)) throw SceneRefused(*refusal);
  }
  std::map<const XmlElement*, uint32_t> groups;
  for (const XmlElement& c : xml.root.children) {
    if (c.tag == "sensor" || c.tag == "integrator") continue;
    if (c.tag == "shape") {
      read_shape(ctx, c, scene.meshes, false, groups);
    } else if (c.tag == "emitter") {
      read_emitter(ctx, c);
    } else if (c.tag == "bsdf" || c.tag == "texture") {
      if (c.find("id") == nullptr)
        ctx.warn_once("unused " + c.tag, c, "ignored: it has no id, so nothing uses it");
    } else {
      c.fail("<" + printable(c.tag, 32) +
             "> is not supported here (docs/mitsuba.md lists what is)");
    }
  }
  for (const fs::path& f : xml.files.read) scene.referenced.push_back(f);
  return scene;
}

}  // namespace rayfarm
