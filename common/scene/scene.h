#pragma once
// The scene as the renderer sees it: every shape resolved to triangles or spheres, every material
// and light validated. Produced by load_scene() (parser.h); see docs/scene-format.md.
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "common/limits.h"
#include "common/math/vec2.h"
#include "common/math/vec3.h"
#include "common/math/vec4.h"
#include "common/scene/frames.h"
#include "common/scene/textures.h"

namespace rayfarm {

/// Version of the scene format that this build reads (the file's optional "format" field).
inline constexpr int kSceneFormatVersion = 1;

/// A perspective (thin-lens) or orthographic camera. Right-handed: the image's right is
/// forward x up.
struct Camera {
  enum class Projection : uint8_t { kPerspective, kOrthographic };
  Projection projection = Projection::kPerspective;
  float view_height = 1.f;  ///< orthographic: height of the visible region, scene units
  Vec3 eye{0.f, 0.f, 0.f};
  Vec3 look_at{0.f, 0.f, 1.f};
  Vec3 up{0.f, 1.f, 0.f};
  float fov_y_deg = 40.f;       ///< vertical field of view, degrees
  float aperture_radius = 0.f;  ///< lens radius in scene units; 0 = pinhole
  float focus_distance = 0.f;   ///< distance to the plane in focus; 0 = |look_at - eye|
  /// A crop: the film is the window at (crop_x, crop_y) of an image of full_width x
  /// full_height pixels, whose aspect ratio the field of view refers to. 0: no crop.
  uint32_t full_width = 0, full_height = 0, crop_x = 0, crop_y = 0;
};

struct FilmSize {
  uint32_t width = 0;
  uint32_t height = 0;
};

/// The pixel reconstruction filter (film.filter; docs/scene-format.md, "Film"). A pixel's value
/// is the image seen through the filter centred on the pixel, normalised to integrate to one, in
/// x and y alike (separable). Each sample's position is drawn from the filter and weighed so that
/// the pixel's mean is exactly that: pixels stay independent of one another, so tiles, passes and
/// the farm's bits are as with the box (renderer/pixel_filter.h).
enum class FilterType : uint8_t {
  kBox,             ///< 1 within radius
  kTent,            ///< 1 - |x| / radius
  kGaussian,        ///< exp(-x^2 / 2 stddev^2), less its value at radius = 4 stddev (Mitsuba's)
  kMitchell,        ///< Mitchell-Netravali cubic (b, c), radius 2; Catmull-Rom is b 0, c 1/2
  kLanczos,         ///< sinc(x) sinc(x / lobes), radius = lobes
  kBlackmanHarris,  ///< the 4-term Blackman-Harris window over [-radius, radius] (Cycles')
};

/// Widest and narrowest filter radius, in pixels.
inline constexpr float kMaxFilterRadius = 8.f;
inline constexpr float kMinFilterRadius = 1e-3f;

struct PixelFilter {
  FilterType type = FilterType::kBox;
  float radius = 0.5f;                 ///< the support on each axis is [-radius, radius], in pixels
  float stddev = 0.5f;                 ///< kGaussian (radius is 4 stddev)
  float b = 1.f / 3.f, c = 1.f / 3.f;  ///< kMitchell
  /// Samples may land beyond the image's edges (true), or the filter of a pixel near an edge is
  /// cut at the edge and renormalised (false, Mitsuba's default: only the image is sampled).
  bool sample_border = true;
  /// 0: the filter as defined. n > 0: the filter as Mitsuba's scalar variants evaluate it, a
  /// table of n steps over [0, radius] each holding the value at its inner end (n = 31), which
  /// makes it a little wider (a Gaussian's standard deviation 0.512 instead of 0.499).
  uint32_t steps = 0;

  /// The box of the pixel's own area: each sample lands in its pixel with weight 1.
  bool pixel_box() const { return type == FilterType::kBox && radius == 0.5f; }
};

/// "box", "tent", "gaussian", "mitchell", "lanczos", "blackman-harris".
const char* filter_name(FilterType type);

// ---- materials: one parameter struct per kind (docs/scene-format.md) ----
// Adding a kind: its struct here, one line in MaterialKind, its reader in material_reader.cpp, and
// its BSDF in renderer/bsdfs/ (one header, one line in the worker's Bsdf).

/// Lambertian reflection.
struct DiffuseMaterial {
  static constexpr const char* kName = "diffuse";
  TexturedRgb albedo{Vec3(0.8f)};  ///< reflectance
  static constexpr auto textured() { return std::make_tuple(&DiffuseMaterial::albedo); }
};

/// Normalised Phong: a diffuse and a glossy lobe, kd + ks <= 1 in every channel.
struct PhongMaterial {
  static constexpr const char* kName = "phong";
  Vec3 kd{0.f};          ///< diffuse reflectance
  Vec3 ks{0.f};          ///< specular reflectance
  float exponent = 1.f;  ///< specular exponent
  static constexpr auto textured() { return std::tuple<>(); }
};

/// Perfect specular reflection.
struct MirrorMaterial {
  static constexpr const char* kName = "mirror";
  TexturedRgb reflectance{Vec3(1.f)};
  static constexpr auto textured() { return std::make_tuple(&MirrorMaterial::reflectance); }
};

/// Smooth glass: Fresnel reflection and refraction.
struct DielectricMaterial {
  static constexpr const char* kName = "dielectric";
  float ior = 1.5f;             ///< index of refraction inside / outside
  TexturedRgb tint{Vec3(1.f)};  ///< transmission colour
  static constexpr auto textured() { return std::make_tuple(&DielectricMaterial::tint); }
};

/// The distribution of microfacet normals of a rough kind: GGX (Trowbridge-Reitz), with long
/// tails, or Beckmann, a Gaussian of the slopes (a sharper highlight with less haze around it).
enum class MicrofacetType : uint8_t { kGgx, kBeckmann };

/// A metal with GGX or Beckmann microfacets: exact conductor Fresnel from eta + i k, or Schlick's
/// from f0. alpha 0 on both axes is a smooth conductor (a Dirac lobe).
struct RoughConductorMaterial {
  static constexpr const char* kName = "roughconductor";
  /// Gold's complex index per channel (linear sRGB, red green blue): the values renderers
  /// commonly use for gold, reduced from Johnson and Christy's 1972 measurements.
  Vec3 eta{0.143119f, 0.374957f, 1.44248f};
  Vec3 k{3.98316f, 2.38572f, 1.60322f};
  bool use_f0 = false;           ///< Schlick's approximation with f0 instead of eta, k
  TexturedRgb f0{Vec3(1.f)};     ///< reflectance at normal incidence, when use_f0
  TexturedFloat alpha_u = 0.1f;  ///< roughness along the surface tangent
  TexturedFloat alpha_v = 0.1f;  ///< roughness along the bitangent
  TexturedRgb specular_reflectance{Vec3(1.f)};  ///< multiplier
  MicrofacetType distribution = MicrofacetType::kGgx;
  static constexpr auto textured() {
    return std::make_tuple(&RoughConductorMaterial::f0, &RoughConductorMaterial::alpha_u,
                           &RoughConductorMaterial::alpha_v,
                           &RoughConductorMaterial::specular_reflectance);
  }
};

/// Glass with GGX or Beckmann microfacets: rough reflection and refraction (Walter et al. 2007).
/// alpha 0 is the smooth dielectric.
struct RoughDielectricMaterial {
  static constexpr const char* kName = "roughdielectric";
  float ior = 1.5f;
  TexturedFloat alpha_u = 0.1f;
  TexturedFloat alpha_v = 0.1f;
  TexturedRgb tint{Vec3(1.f)};  ///< transmission colour
  MicrofacetType distribution = MicrofacetType::kGgx;
  static constexpr auto textured() {
    return std::make_tuple(&RoughDielectricMaterial::alpha_u, &RoughDielectricMaterial::alpha_v,
                           &RoughDielectricMaterial::tint);
  }
};

/// A pane of glass of zero thickness: specular reflection including the pane's inner bounces,
/// and straight-through transmission.
struct ThinDielectricMaterial {
  static constexpr const char* kName = "thindielectric";
  float ior = 1.5f;
  TexturedRgb tint{Vec3(1.f)};
  static constexpr auto textured() { return std::make_tuple(&ThinDielectricMaterial::tint); }
};

class RoughCoatTable;  // renderer/bsdfs/rough_coat.h

/// A diffuse base under a smooth (alpha 0) or rough (GGX or Beckmann) dielectric coating.
struct PlasticMaterial {
  static constexpr const char* kName = "plastic";
  TexturedRgb diffuse_reflectance{Vec3(0.5f)};
  float ior = 1.49f;          ///< of the coating (polypropylene)
  TexturedFloat alpha = 0.f;  ///< roughness of the coating; 0 = smooth
  bool nonlinear = false;     ///< internal reflections darken and saturate the base's colour
  MicrofacetType distribution = MicrofacetType::kGgx;
  /// What a rough coating lets through to the base, tabulated by the worker when it prepares
  /// the scene (renderer/bsdfs/rough_coat.h); null until then, and for a smooth coating.
  const RoughCoatTable* coat_table = nullptr;
  static constexpr auto textured() {
    return std::make_tuple(&PlasticMaterial::diffuse_reflectance, &PlasticMaterial::alpha);
  }
};

/// The glTF 2.0 metallic-roughness BRDF (with KHR_materials_ior and _transmission).
struct MetallicRoughnessMaterial {
  static constexpr const char* kName = "metallic_roughness";
  TexturedRgb base_color{Vec3(1.f)};
  TexturedFloat metallic = 1.f;
  TexturedFloat roughness = 1.f;  ///< GGX alpha = roughness^2
  float ior = 1.5f;
  TexturedFloat transmission = 0.f;
  static constexpr auto textured() {
    return std::make_tuple(
        &MetallicRoughnessMaterial::base_color, &MetallicRoughnessMaterial::metallic,
        &MetallicRoughnessMaterial::roughness, &MetallicRoughnessMaterial::transmission);
  }
};

/// Every material kind, in the order the scene format lists them.
using MaterialKind =
    std::variant<DiffuseMaterial, PhongMaterial, MirrorMaterial, DielectricMaterial,
                 RoughConductorMaterial, RoughDielectricMaterial, ThinDielectricMaterial,
                 PlasticMaterial, MetallicRoughnessMaterial>;

/// Name of a material kind as written in scene files ("diffuse", ...).
inline const char* material_kind_name(const MaterialKind& kind) {
  return std::visit([](const auto& k) { return k.kName; }, kind);
}

/// A tangent-space normal map: RGB in [0, 1] read linear, mapped to [-1, 1]; x along the tangent,
/// y along the bitangent (the image's up), z along the shading normal; x and y times `scale`.
struct NormalMap {
  uint32_t texture = 0;  ///< index into Scene::textures
  float scale = 1.f;
};

/// A height field over the surface: the texture's value (RGB mean, read linear) times `scale`,
/// in scene units along the shading normal. Only the normal it implies is used.
struct BumpMap {
  uint32_t texture = 0;  ///< index into Scene::textures
  float scale = 1.f;
};

/// One material: its kind's parameters, and what any kind may carry: emission, a normal or bump
/// map, an alpha cut-out.
struct Material {
  std::string name;
  MaterialKind kind;                ///< default: diffuse, albedo 0.8
  TexturedRgb emission{Vec3(0.f)};  ///< emitted radiance; non-zero makes an area light
  bool two_sided = false;           ///< emission leaves both sides
  bool textured = false;  ///< some BSDF parameter reads a texture (set by the scene's reader)
  /// The kind's colours (its TexturedRgb parameters: glTF's base colour) are multiplied by the
  /// hit mesh's interpolated TriangleMesh::colours, as glTF's COLOR_0 asks.
  bool vertex_colours = false;
  /// The BSDF scatters nothing from behind (the side against the geometric normal); opaque
  /// kinds only. Off: every opaque kind reflects on both sides alike.
  bool one_sided = false;
  /// With one_sided: scatters only between directions above the shading normal's horizon (the
  /// normal a normal or bump map makes, else the interpolated one), as Mitsuba 3's BSDFs do; a
  /// mapped normal is kept even where it leans beyond the geometric horizon.
  bool shading_sided = false;
  std::optional<NormalMap> normal_map;
  std::optional<BumpMap> bump_map;
  /// Coverage: a hit where alpha < alpha_cutoff is not there (rays pass straight through).
  TexturedFloat alpha = 1.f;
  float alpha_cutoff = 0.5f;
  /// Partial coverage instead of a cut-out: a hit is there with probability alpha, decided from
  /// a hash of the hit point (the same ray decides the same way; different rays independently),
  /// so that the image converges to alpha times the surface plus 1 - alpha times what is behind.
  bool alpha_blend = false;

  bool is_emissive() const { return !is_black(emission.value); }
  /// Whether some hits on it are cut out; a constant alpha of 1 never is.
  bool has_alpha() const {
    return alpha.is_textured() || alpha.value < (alpha_blend ? 1.f : alpha_cutoff);
  }
  /// Whether shading it perturbs the normal.
  bool has_surface_map() const { return normal_map.has_value() || bump_map.has_value(); }
  /// Whether anything of it reads texture coordinates.
  bool uses_uv() const {
    return textured || emission.is_textured() || has_surface_map() || alpha.is_textured();
  }
};

/// Triangles with one material index each. The front face is (v1-v0) x (v2-v0).
struct TriangleMesh {
  std::vector<Vec3> positions;
  /// Shading normals per vertex (unit length), or empty: every triangle is flat. A triangle with
  /// a zero normal at any of its vertices is flat too.
  std::vector<Vec3> normals;
  /// Texture coordinates per vertex, or empty: (u, v) are then the hit's barycentrics.
  std::vector<Vec2> uvs;
  /// Tangents per vertex, or empty (then derived from the texture coordinates): xyz a unit
  /// tangent, w = +-1 the handedness, the bitangent being w * cross(normal, tangent).
  std::vector<Vec4> tangents;
  /// Linear RGB per vertex (glTF COLOR_0), or empty: multiplies the colour of a material with
  /// Material::vertex_colours (1 where a mesh has none).
  std::vector<Vec3> colours;
  std::vector<uint32_t> indices;    ///< 3 per triangle, into positions (and normals, uvs)
  std::vector<uint32_t> materials;  ///< 1 per triangle, into Scene::materials
  std::string origin;               ///< where it came from, for messages ("box.obj", "shapes[3]")

  size_t triangle_count() const { return indices.size() / 3; }
};

/// Meshes in their own (object) space, placed in the world by instances: their triangles are
/// stored once however often they are placed.
struct MeshGroup {
  std::string name;
  std::vector<TriangleMesh> meshes;  ///< object space
};

/// One placement of a group. world_from_object is a 4x4 affine matrix, row-major (the last row
/// 0 0 0 1), invertible; a mirroring one (negative determinant) keeps front faces outward.
struct Instance {
  uint32_t group = 0;  ///< into Scene::groups
  std::array<double, 16> world_from_object{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
};

/// A sphere; its front side is the outside. Its texture coordinates are taken in its own frame
/// (the rotation of its transform): u = phi / 2pi around local +z from local +x, v = theta / pi
/// from local +z.
struct Sphere {
  Vec3 center;
  float radius = 1.f;
  uint32_t material = 0;
  Vec3 axis_x{1.f, 0.f, 0.f}, axis_y{0.f, 1.f, 0.f}, axis_z{0.f, 0.f, 1.f};  ///< unit, orthogonal
};

/// Isotropic point light; intensity is radiant intensity in W/sr per RGB channel.
struct PointLight {
  Vec3 position;
  Vec3 intensity;
};

/// A point light emitting into a cone: full intensity (W/sr) within beam_width of the axis,
/// falling linearly in angle to zero at cutoff (docs/scene-format.md, "Lights").
/// An image a spot light casts (Mitsuba's textured `spot`, its `projector`): the light's
/// intensity towards a direction is multiplied by the image at the direction's (u, v), found in
/// the light's frame (x_axis, y_axis, and the spot's direction as z) as
/// u = 0.5 + u_scale x / z, v = 0.5 + v_scale y / z (renderer/lights/image_spot_light.h).
struct SpotImage {
  TexturedRgb image{Vec3(1.f)};  ///< a texture (looked up at that (u, v)) or a constant
  Vec3 x_axis{1.f, 0.f, 0.f}, y_axis{0.f, 1.f, 0.f};  ///< unit, orthogonal to the direction
  float u_scale = 0.5f, v_scale = 0.5f;
  /// A projector: it lights only the image's rectangle (u, v in [0, 1]), without the cone's
  /// falloff, its intensity divided by cos^3 of the angle to the axis (so that a plane facing it
  /// at distance 1 receives intensity x image, evenly).
  bool projector = false;
};

struct SpotLight {
  Vec3 position;
  Vec3 direction{0.f, 0.f, 1.f};  ///< unit axis of the cone, away from the light
  Vec3 intensity;
  float cutoff_deg = 20.f;      ///< half-angle of the cone; no light beyond it
  float beam_width_deg = 15.f;  ///< half-angle of full intensity, <= cutoff_deg
  std::optional<SpotImage> image;  ///< an image it casts; none: the plain spot
};

/// Parallel light from infinitely far away.
struct DirectionalLight {
  Vec3 direction{0.f, -1.f, 0.f};  ///< unit direction the light travels
  Vec3 irradiance;                 ///< W/m^2 on a surface facing the light
};

/// Light arriving from every direction at infinity: an equirectangular image (radiance = texel
/// times scale), or a constant radiance. Its orientation is in docs/scene-format.md, "Lights".
struct EnvironmentMap {
  std::filesystem::path file;  ///< image, relative to the scene's folder; empty: constant
  /// The decoded image; null for a constant or when the scene was loaded only to be checked.
  std::shared_ptr<const DecodedImage> image;
  Vec3 scale{1.f};  ///< image: factor on every texel; constant: the radiance
  /// World from map (a rotation), row-major: the map's own +y is up, its centre looks along +z.
  std::array<double, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};
  /// How an image is read between texels: false, the texel a direction falls in (each texel a
  /// cell of the image); true, bilinear interpolation between texel centres placed as Mitsuba 3's
  /// envmap places them: column i at u = (i + 1/2) / width (wrapping around), row j at
  /// v = j / (height - 1) (the first row straight up, the last straight down).
  bool bilinear = false;
};

enum class IntegratorType : uint8_t { kNaive, kNee, kMis };

/// Name used in scene files and on the command line ("naive", "nee", "mis").
const char* integrator_name(IntegratorType type);
/// Parses an integrator name; nullopt when unknown.
std::optional<IntegratorType> parse_integrator(const std::string& name);

/// Where a sample's random numbers come from (renderer/samplers/path_sampler.h).
enum class SamplerType : uint8_t {
  kIndependent,  ///< one hashed random stream per sample
  kSobol,        ///< Owen-scrambled Sobol' points per group of dimensions, then the stream
};
/// "independent" or "sobol".
const char* sampler_name(SamplerType type);
std::optional<SamplerType> parse_sampler(const std::string& name);

/// How Russian roulette ends paths (docs/scene-format.md, "Render settings").
enum class RouletteType : uint8_t {
  /// At every vertex, survival min(1, largest component of the BSDF's throughput update).
  kUpdate,
  /// From vertex roulette_depth on, survival min(1, largest component of the path's throughput
  /// times eta^2 for each refraction it went through).
  kThroughput,
  /// As kThroughput, survival the fourth root of that (throughput_survival(),
  /// renderer/integrators/path_integrator.h): dim paths are spared at first.
  kRoot,
};
/// "update", "throughput" or "root".
const char* roulette_name(RouletteType type);
std::optional<RouletteType> parse_roulette(const std::string& name);

/// How to render: the scene's defaults, overridden by the command line or the job.
struct RenderSettings {
  uint32_t spp = kDefaultSpp;  ///< samples per pixel
  /// Most scattering vertices per path: the surface hits at which light is sampled and a BSDF
  /// direction drawn, the camera ray's hit being the first. Emission found by the last scattered
  /// ray still counts. 1 = direct lighting only; 0 = emitters seen by the camera only;
  /// kUnlimitedDepth = no cap (Russian roulette alone ends paths).
  uint32_t max_depth = kDefaultMaxDepth;
  IntegratorType integrator = IntegratorType::kMis;
  uint64_t seed = 0;  ///< selects the random streams; same seed, same image
  /// When positive, a sample whose largest component exceeds it is scaled down to it: fewer
  /// fireflies, at the cost of a bias (the image no longer converges to the true one). 0 = off.
  float clamp = 0.f;
  SamplerType sampler = SamplerType::kSobol;
  RouletteType roulette = RouletteType::kRoot;
  /// kRoot, kThroughput: the vertex (0 = the camera ray's hit) from which roulette may end a path.
  uint32_t roulette_depth = kDefaultRouletteDepth;
  /// Motion blur: the shutter is open from frame + shutter_open to frame + shutter_close (in
  /// frames, open <= close); each sample is taken at its own time within it. Closed (equal) by
  /// default, and on a still scene nothing moves.
  float shutter_open = 0.f, shutter_close = 0.f;
  /// Times within an open shutter at which the scene is posed; moving shapes and the camera
  /// move linearly between them.
  uint32_t motion_steps = kDefaultMotionSteps;

  bool shutter_is_open() const { return shutter_close > shutter_open; }
};

/// max_depth as written: a number or "unlimited".
std::string depth_name(uint32_t max_depth);
/// Parses a max_depth ("unlimited" or 0..kMaxDepth); nullopt when neither.
std::optional<uint32_t> parse_depth(const std::string& text);

struct SceneMotion;  // common/scene/motion.h

struct Scene {
  Camera camera;
  FilmSize film;
  PixelFilter filter;  ///< the film's reconstruction filter
  std::vector<Material> materials;
  std::vector<TextureDesc> textures;  ///< what textured material parameters read
  std::vector<TriangleMesh> meshes;
  std::vector<Sphere> spheres;
  std::vector<MeshGroup> groups;    ///< meshes that instances place
  std::vector<Instance> instances;  ///< placements of groups
  std::vector<PointLight> point_lights;
  std::vector<SpotLight> spot_lights;
  std::vector<DirectionalLight> directional_lights;
  std::optional<EnvironmentMap> environment;  ///< at most one per scene
  Vec3 background{0.f};                       ///< radiance of rays that escape
  RenderSettings render;
  /// An animated scene's frames (its "animation" block), and the frame this Scene is of; both
  /// nullopt for a still scene.
  std::optional<FrameRange> animation;
  std::optional<int64_t> frame;
  /// What moves while the shutter is open (add_motion(), common/scene/motion.h); null when
  /// nothing does or nobody asked.
  std::shared_ptr<const SceneMotion> motion;

  std::filesystem::path source;                   ///< the scene file
  std::vector<std::filesystem::path> referenced;  ///< files it uses, relative to its folder
  std::vector<std::string> warnings;              ///< non-fatal problems found while loading
  /// The camera is a default placed from the meshes' bounds (a glTF file without one): it is
  /// placed anew at each frame, and kept still within a shutter rather than chasing the meshes.
  bool default_camera = false;
};

/// The end of the warning a scene without light gets (after its file's name; has_light(),
/// common/scene/instances.h).
inline constexpr const char* kNoLightWarning =
    ": the scene has no light (no light, emissive surface, environment or background): every "
    "image of it is black; add a light (a glTF file: --environment uniform), or an \"environment\" "
    "or \"background\" in a JSON scene";

/// Releases the decoded texture images a loaded scene holds, once a renderer has taken its copy.
inline void drop_images(Scene& scene) {
  for (TextureDesc& t : scene.textures) t.image.reset();
  if (scene.environment) scene.environment->image.reset();
}

}  // namespace rayfarm
