#pragma once
// How a texture is looked up, as a scene states it (docs/textures.md): the colour space of its
// samples, its filter, wrap modes, UV transform and UV origin. The scene describes textures with
// these; the worker's textures (renderer/textures/) apply them.
#include <array>
#include <optional>

namespace rayfarm {

/// How a texture's colour samples are encoded. `from_file`: as the file says
/// (DecodedImage::display_encoded); a scene may override it either way (e.g. a normal map in a
/// PNG is `linear`). Alpha is always linear.
enum class ColourSpace { from_file, srgb, linear };

/// What a scene states. `rotation` (radians) turns the UVs counter-clockwise about the origin,
/// which turns the image clockwise: u' = cos r * su u + sin r * sv v + offset_u,
/// v' = -sin r * su u + cos r * sv v + offset_v.
struct UvTransform {
  std::array<float, 2> offset{0.f, 0.f};
  std::array<float, 2> scale{1.f, 1.f};
  float rotation = 0.f;
  /// When set, the whole map instead: u' = m0 u + m1 v + m2, v' = m3 u + m4 v + m5 (Mitsuba's
  /// to_uv, which may shear).
  std::optional<std::array<float, 6>> matrix;
};

enum class TextureFilter { bilinear, nearest };
/// Outside [0, 1): repeat the image, repeat it mirrored every other time, or extend its edge.
enum class TextureWrap { repeat, mirror, clamp };
/// Where uv (0, 0) is on the image: its bottom-left corner (OBJ, Mitsuba) or its top-left one
/// (glTF).
enum class UvOrigin { bottom_left, top_left };

struct ImageTextureOptions {
  TextureFilter filter = TextureFilter::bilinear;
  TextureWrap wrap_u = TextureWrap::repeat;
  TextureWrap wrap_v = TextureWrap::repeat;
  /// Applied to (u, v) first; the origin then places the result on the image.
  UvTransform transform;
  UvOrigin origin = UvOrigin::bottom_left;
};

}  // namespace rayfarm
