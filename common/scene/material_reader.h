#pragma once
// The scene format's material kinds: one reader per kind, each checking its keys and ranges.
#include <string>
#include <vector>

#include "common/scene/json_reader.h"
#include "common/scene/scene.h"
#include "common/scene/texture_reader.h"

namespace rayfarm::scene_json {

/// Reads the parameters of the material type `type` (a kind's name or a synonym such as
/// "conductor") from `n`, textured parameters naming the textures `tex` has read; false when no
/// kind has that name.
bool read_material_kind(const Node& n, const std::string& type, MaterialKind& out,
                        const rayfarm::TextureReader& tex);

/// What any kind may carry (docs/scene-format.md, "Surfaces"): emission, one_sided, a normal or
/// bump map, an opacity cut-out. Data textures that a map reads are switched to linear.
void read_surface(const Node& n, Material& m, const rayfarm::TextureReader& tex,
                  std::vector<TextureDesc>& textures);

/// "diffuse, phong, ...": every accepted type name, for messages.
std::string material_type_names();

}  // namespace rayfarm::scene_json
