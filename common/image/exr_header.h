#pragma once
// The data window of an OpenEXR header, read without OpenEXR: its InputFile allocates a table
// sized by the header as it opens a file, so a reader checks the size first.
#include <cstdint>
#include <optional>
#include <string_view>
#include <utility>

namespace rayfarm {

/// The (width, height) of the data window in the header at the start of `head` (the first bytes
/// of an EXR file); the last one when the header has several, as OpenEXR reads it. nullopt when
/// `head` holds no complete, well-formed header with a data window.
std::optional<std::pair<int64_t, int64_t>> peek_exr_data_window(std::string_view head);

}  // namespace rayfarm
