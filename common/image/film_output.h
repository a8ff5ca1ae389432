#pragma once
// The one way a film becomes files: an EXR of the current estimate and a PNG preview beside it.
// `rayfarm render` and the master both write through here, so their EXRs hold the same bits.
#include <filesystem>
#include <map>
#include <string>

#include "common/image/exr.h"
#include "common/image/film.h"

namespace rayfarm {

/// The film's current estimate as an image, with the layers "variance" (of each pixel's mean) and
/// "spp"; attribute "rayfarm:spp" records the fewest samples
/// of any pixel, "rayfarm:nonfinite" the samples dropped.
Image film_to_image(const Film& film, const std::map<std::string, std::string>& attributes);

/// Path of the PNG preview written beside an EXR ("out.exr" -> "out.png").
std::filesystem::path preview_path(const std::filesystem::path& exr);

/// Writes the EXR and its PNG preview, each atomically (temporary file + rename).
void write_film(const std::filesystem::path& exr, const Film& film,
                const std::map<std::string, std::string>& attributes);

}  // namespace rayfarm
