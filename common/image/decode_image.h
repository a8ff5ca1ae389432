#pragma once
// Decoding of image textures (PNG, JPEG, OpenEXR, Radiance HDR) from bytes in memory: the bytes
// come from a scene bundle, never from a path of the machine. docs/textures.md.
#include <cstdint>
#include <span>
#include <string>

#include "common/image/decoded_image.h"

namespace rayfarm {

/// Decodes `bytes`, choosing the format by its magic bytes (not by the name's extension). Throws
/// SceneError "NAME: what, where" for an unknown format, a size over kMaxTextureSide or
/// kMaxTexturePixels (checked from the header, before any pixel is allocated), and truncated or
/// corrupt data; never returns a partial image. Thread-safe: decodes share no state.
DecodedImage decode_image(std::span<const uint8_t> bytes, const std::string& name);

}  // namespace rayfarm
