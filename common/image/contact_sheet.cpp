#include "common/image/contact_sheet.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/image/png.h"

namespace rayfarm {
namespace {

constexpr uint8_t kBackground = 16;  // between cells
constexpr uint8_t kEmptyCell = 48;   // a frame without a picture yet

/// Digits and '-' in a 3x5 pixel font, one row per entry, the top row first, bit 2 the left.
constexpr uint8_t kGlyphs[11][5] = {{7, 5, 5, 5, 7}, {2, 6, 2, 2, 7}, {7, 1, 7, 4, 7},
                                    {7, 1, 7, 1, 7}, {5, 5, 7, 1, 1}, {7, 4, 7, 1, 7},
                                    {7, 4, 7, 5, 7}, {7, 1, 1, 1, 1}, {7, 5, 7, 5, 7},
                                    {7, 5, 7, 1, 7}, {0, 0, 7, 0, 0}};

void fill(Rgb8Image& img, uint32_t x0, uint32_t y0, uint32_t w, uint32_t h, uint8_t value) {
  const uint32_t x1 = std::min(img.width, x0 + w), y1 = std::min(img.height, y0 + h);
  for (uint32_t y = y0; y < y1; ++y) {
    std::fill(img.rgb.begin() + (size_t{y} * img.width + x0) * 3,
              img.rgb.begin() + (size_t{y} * img.width + x1) * 3, value);
  }
}

/// The frame number in white on black at the cell's bottom left, as much of it as fits.
void draw_label(Rgb8Image& img, uint32_t cx, uint32_t cy, const SheetLayout& layout,
                int64_t frame) {
  const std::string text = std::to_string(frame);
  const uint32_t scale = layout.cell_height >= 64 ? 2 : 1;
  const uint32_t glyph_w = 3 * scale, glyph_h = 5 * scale, pad = scale;
  const uint32_t box_h = glyph_h + 2 * pad;
  if (box_h > layout.cell_height) return;
  const uint32_t fits = (layout.cell_width - pad) / (glyph_w + pad);
  const size_t shown = std::min<size_t>(text.size(), fits);
  if (shown == 0) return;
  const uint32_t box_w = static_cast<uint32_t>(shown) * (glyph_w + pad) + pad;
  const uint32_t by = cy + layout.cell_height - box_h;
  fill(img, cx, by, box_w, box_h, 0);
  for (size_t i = 0; i < shown; ++i) {
    const char c = text[i];
    const auto& glyph = kGlyphs[c == '-' ? 10 : c - '0'];
    const uint32_t gx = cx + pad + static_cast<uint32_t>(i) * (glyph_w + pad);
    for (uint32_t row = 0; row < 5; ++row) {
      for (uint32_t col = 0; col < 3; ++col) {
        if (glyph[row] & (4u >> col))
          fill(img, gx + col * scale, by + pad + row * scale, scale, scale, 255);
      }
    }
  }
}

}  // namespace

uint32_t SheetLayout::width() const { return columns * (cell_width + kSheetGap) + kSheetGap; }
uint32_t SheetLayout::height() const { return rows * (cell_height + kSheetGap) + kSheetGap; }

SheetLayout sheet_layout(size_t count, uint32_t width, uint32_t height) {
  if (count == 0 || width == 0 || height == 0) {
    throw std::invalid_argument("a contact sheet needs at least one frame of a non-empty size");
  }
  const double aspect = double(width) / double(height);
  SheetLayout out;
  // Columns for a sheet of about 16:9: columns * w / (rows * h) = 16/9, rows = count / columns.
  const double columns = std::ceil(std::sqrt(double(count) * 16.0 / 9.0 / aspect));
  out.columns = static_cast<uint32_t>(std::clamp<double>(columns, 1.0, double(count)));
  out.rows = static_cast<uint32_t>((count + out.columns - 1) / out.columns);
  // The frame scaled by s: its longer side kSheetCellSide at most (never enlarged), narrow
  // enough for the columns to fit kSheetMaxWidth, but the longer side kSheetMinCellSide at least.
  const double longer = std::max(width, height);
  const double room = double(kSheetMaxWidth - kSheetGap) / out.columns - kSheetGap;
  double s = std::min(1.0, kSheetCellSide / longer);
  s = std::min(s, room / width);
  s = std::max(s, std::min(1.0, kSheetMinCellSide / longer));
  out.cell_width = std::max<uint32_t>(1, static_cast<uint32_t>(std::floor(width * s)));
  out.cell_height = std::max<uint32_t>(1, static_cast<uint32_t>(std::floor(height * s)));
  return out;
}

Rgb8Image thumbnail(const Image& image, uint32_t width, uint32_t height) {
  if (image.width == 0 || image.height == 0 || width == 0 || height == 0 ||
      image.rgb.size() != size_t{image.width} * image.height * 3) {
    throw std::invalid_argument("cannot make a " + std::to_string(width) + "x" +
                                std::to_string(height) + " thumbnail of a " +
                                std::to_string(image.width) + "x" + std::to_string(image.height) +
                                " image");
  }
  // Each thumbnail pixel is the mean of the image pixels whose centres fall in its footprint
  // (at least one).
  auto span = [](uint32_t i, uint32_t from, uint32_t to) {
    const uint32_t lo = static_cast<uint32_t>(uint64_t{i} * from / to);
    const uint32_t hi = static_cast<uint32_t>(uint64_t{i + 1} * from / to);
    return std::pair{lo, std::max(hi, lo + 1)};
  };
  Image small;
  small.width = width;
  small.height = height;
  small.rgb.resize(size_t{width} * height * 3);
  for (uint32_t y = 0; y < height; ++y) {
    const auto [y0, y1] = span(y, image.height, height);
    for (uint32_t x = 0; x < width; ++x) {
      const auto [x0, x1] = span(x, image.width, width);
      double sum[3] = {0, 0, 0};
      for (uint32_t sy = y0; sy < y1; ++sy) {
        for (uint32_t sx = x0; sx < x1; ++sx) {
          const float* p = &image.rgb[(size_t{sy} * image.width + sx) * 3];
          for (int c = 0; c < 3; ++c) sum[c] += std::isfinite(p[c]) ? p[c] : 0.0;
        }
      }
      const double n = double(y1 - y0) * double(x1 - x0);
      for (int c = 0; c < 3; ++c) {
        small.rgb[(size_t{y} * width + x) * 3 + c] = static_cast<float>(sum[c] / n);
      }
    }
  }
  return Rgb8Image{width, height, preview_pixels(small)};
}

Rgb8Image contact_sheet(const SheetLayout& layout, const std::vector<SheetCell>& cells) {
  if (cells.size() > size_t{layout.columns} * layout.rows) {
    throw std::invalid_argument("a contact sheet of " + std::to_string(cells.size()) +
                                " frames does not fit its layout");
  }
  Rgb8Image sheet{layout.width(), layout.height(), {}};
  sheet.rgb.assign(size_t{sheet.width} * sheet.height * 3, kBackground);
  for (size_t i = 0; i < cells.size(); ++i) {
    const uint32_t cx =
        kSheetGap + static_cast<uint32_t>(i % layout.columns) * (layout.cell_width + kSheetGap);
    const uint32_t cy =
        kSheetGap + static_cast<uint32_t>(i / layout.columns) * (layout.cell_height + kSheetGap);
    const Rgb8Image* pic = cells[i].picture;
    if (pic == nullptr) {
      fill(sheet, cx, cy, layout.cell_width, layout.cell_height, kEmptyCell);
    } else {
      if (pic->width != layout.cell_width || pic->height != layout.cell_height) {
        throw std::invalid_argument("a contact sheet's picture is not of its cell size");
      }
      for (uint32_t y = 0; y < pic->height; ++y) {
        std::copy_n(pic->rgb.begin() + size_t{y} * pic->width * 3, size_t{pic->width} * 3,
                    sheet.rgb.begin() + (size_t{cy + y} * sheet.width + cx) * 3);
      }
    }
    draw_label(sheet, cx, cy, layout, cells[i].frame);
  }
  return sheet;
}

}  // namespace rayfarm
