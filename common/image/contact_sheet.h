#pragma once
// A contact sheet: small pictures of a sequence's frames side by side in one 8-bit image, each
// labelled with its frame number, so that a whole sequence can be looked at at once.
#include <cstdint>
#include <vector>

#include "common/image/exr.h"

namespace rayfarm {

/// An 8-bit sRGB picture: width * height * 3 bytes, row-major, top row first.
struct Rgb8Image {
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<uint8_t> rgb;
};

/// Where the cells of a sheet go: `columns` x `rows` cells of cell_width x cell_height pixels,
/// kSheetGap pixels apart and from the edges.
struct SheetLayout {
  uint32_t columns = 1;
  uint32_t rows = 1;
  uint32_t cell_width = 1;
  uint32_t cell_height = 1;
  uint32_t width() const;
  uint32_t height() const;
};

inline constexpr uint32_t kSheetGap = 4;
/// A cell's longer side when the sheet has room for it.
inline constexpr uint32_t kSheetCellSide = 160;
/// The widest sheet: cells shrink (down to kSheetMinCellSide) to stay within it.
inline constexpr uint32_t kSheetMaxWidth = 4096;
inline constexpr uint32_t kSheetMinCellSide = 8;

/// The layout of `count` (>= 1) pictures of frames `width` x `height`: cells of the frames'
/// aspect, never larger than the frames, in about a 16:9 sheet.
SheetLayout sheet_layout(size_t count, uint32_t width, uint32_t height);

/// `image` resized to exactly `width` x `height` (a box filter over its linear values, then
/// encoded as its PNG preview is: common/image/png.h). Meant for shrinking.
Rgb8Image thumbnail(const Image& image, uint32_t width, uint32_t height);

/// One cell of a sheet: a frame, and its picture (of the layout's cell size) or nullptr when it
/// has none yet (a dark cell).
struct SheetCell {
  int64_t frame = 0;
  const Rgb8Image* picture = nullptr;
};

/// The sheet: the cells left to right, top to bottom, each labelled with its frame number at its
/// bottom left. Throws std::invalid_argument when a picture is not of the cell size or there are
/// more cells than the layout holds.
Rgb8Image contact_sheet(const SheetLayout& layout, const std::vector<SheetCell>& cells);

}  // namespace rayfarm
