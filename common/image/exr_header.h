#pragma once
// An OpenEXR header's attributes, read without OpenEXR: its InputFile allocates a table sized by
// the header as it opens a file, so a reader checks the size first; and the master reads what an
// image says of itself (rayfarm:spp) without decoding it.
#include <cstdint>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

namespace rayfarm {

/// One attribute of an EXR header: views into the bytes it was read from.
struct ExrAttribute {
  std::string_view name, type, value;
};

/// The attributes of the header at the start of `head` (the first bytes of an EXR file), in the
/// order written; nullopt when `head` holds no complete, well-formed header.
std::optional<std::vector<ExrAttribute>> peek_exr_attributes(std::string_view head);

/// The (width, height) of the data window in the header at the start of `head`; the last one when
/// the header has several, as OpenEXR reads it. nullopt when `head` holds no complete, well-formed
/// header with a data window.
std::optional<std::pair<int64_t, int64_t>> peek_exr_data_window(std::string_view head);

}  // namespace rayfarm
