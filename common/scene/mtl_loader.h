#pragma once
// Wavefront MTL material libraries, as the OBJ files of a scene name them (docs/scene-format.md,
// "MTL materials"). Each file is checked and read in one pass over its lines; the statements
// rayfarm does not use are reported once and skipped.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/scene/text_lines.h"

namespace rayfarm {

/// One MTL material as written, with the format's defaults for what it does not say.
struct MtlMaterial {
  std::string name;
  float diffuse[3] = {0.f, 0.f, 0.f};        ///< Kd
  float specular[3] = {0.f, 0.f, 0.f};       ///< Ks
  float transmittance[3] = {0.f, 0.f, 0.f};  ///< Tf (or Kt)
  float emission[3] = {0.f, 0.f, 0.f};       ///< Ke
  float ior = 1.f;                           ///< Ni
  float dissolve = 1.f;                      ///< d, or 1 - Tr when no d is given
  float shininess = 1.f;                     ///< Ns
  int illum = 0;                             ///< illumination model, 0 to 10
};

/// An OBJ file's "mtllib" line: where it is and the file names it gives.
struct MtlLibLine {
  scene_text::Where at;
  std::vector<std::string> names;
};

/// The materials of all MTL files an OBJ names, in file order, first definition of a name kept.
struct MtlLibrary {
  std::vector<MtlMaterial> materials;
  std::vector<scene_text::Where> defined_at;  ///< the newmtl line of each material
  std::map<std::string, int> index;           ///< name -> index into materials
  std::vector<std::filesystem::path> files;   ///< MTL files read, relative to the scene
  std::vector<std::string> warnings;          ///< "FILE:LINE: ..." problems that were tolerated
};

/// Loads every file named by the mtllib lines of `obj` (relative to the scene folder
/// `scene_dir`); names are relative to the OBJ's folder. Throws SceneError "FILE:LINE: ...".
MtlLibrary load_mtllibs(const std::filesystem::path& scene_dir, const std::filesystem::path& obj,
                        const std::vector<MtlLibLine>& mtllibs);

}  // namespace rayfarm
