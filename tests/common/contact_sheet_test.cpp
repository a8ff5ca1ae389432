// Contact sheets: their layout stays about 16:9 and within its widest, thumbnails are box-filtered
// means encoded as previews are, and every cell holds its picture (or the empty grey) and a label.
#include <gtest/gtest.h>

#include "common/image/contact_sheet.h"
#include "common/image/png.h"

namespace rayfarm {
namespace {

Image flat(uint32_t w, uint32_t h, float value) {
  Image img;
  img.width = w;
  img.height = h;
  img.rgb.assign(size_t{w} * h * 3, value);
  return img;
}

TEST(ContactSheet, LayoutIsAboutSixteenByNineAndNeverTooWide) {
  struct Case {
    size_t count;
    uint32_t w, h;
  };
  for (const Case c : {Case{1, 64, 64}, Case{3, 15, 9}, Case{48, 256, 256}, Case{1000, 1920, 1080},
                       Case{7, 16384, 1}, Case{5, 1, 16384}, Case{100000, 64, 64}}) {
    SCOPED_TRACE(testing::Message() << c.count << " of " << c.w << "x" << c.h);
    const SheetLayout l = sheet_layout(c.count, c.w, c.h);
    EXPECT_GE(size_t{l.columns} * l.rows, c.count);
    EXPECT_LT(size_t{l.columns} * (l.rows - 1), c.count);  // no empty row
    EXPECT_LE(l.cell_width, std::max(c.w, kSheetMinCellSide));
    EXPECT_LE(std::max(l.cell_width, l.cell_height), std::max(kSheetCellSide, kSheetMinCellSide));
    EXPECT_GE(l.cell_width, 1u);
    EXPECT_GE(l.cell_height, 1u);
    if (std::max(l.cell_width, l.cell_height) > kSheetMinCellSide) {
      EXPECT_LE(l.width(), kSheetMaxWidth);
    }
    if (c.count >= 16 && c.w == c.h) {
      const double aspect = double(l.width()) / l.height();
      EXPECT_GT(aspect, 1.2);
      EXPECT_LT(aspect, 2.4);
    }
  }
  EXPECT_THROW(sheet_layout(0, 64, 64), std::invalid_argument);
  EXPECT_THROW(sheet_layout(3, 0, 64), std::invalid_argument);
}

TEST(ContactSheet, AThumbnailIsTheMeanOfItsFootprintEncodedAsThePreview) {
  // 4x2 image: left half 0.1, right half 0.9 -> 2x1 thumbnail of one of each.
  Image img = flat(4, 2, 0.1f);
  for (uint32_t y = 0; y < 2; ++y) {
    for (uint32_t x = 2; x < 4; ++x) {
      for (int c = 0; c < 3; ++c) img.rgb[(y * 4 + x) * 3 + c] = 0.9f;
    }
  }
  const Rgb8Image t = thumbnail(img, 2, 1);
  ASSERT_EQ(t.rgb.size(), 6u);
  EXPECT_EQ(t.rgb[0], preview_pixels(flat(1, 1, 0.1f))[0]);
  EXPECT_EQ(t.rgb[3], preview_pixels(flat(1, 1, 0.9f))[0]);
  // Averaging happens before encoding: the mean of 0 and 1 is linear 0.5, not code 128.
  Image half = flat(2, 1, 0.f);
  for (int c = 0; c < 3; ++c) half.rgb[3 + c] = 1.f;
  EXPECT_EQ(thumbnail(half, 1, 1).rgb[0], preview_pixels(flat(1, 1, 0.5f))[0]);
  // A non-finite value counts as black.
  Image bad = flat(2, 1, 0.5f);
  bad.rgb[0] = std::numeric_limits<float>::infinity();
  EXPECT_EQ(thumbnail(bad, 1, 1).rgb[0], preview_pixels(flat(1, 1, 0.25f))[0]);
  EXPECT_THROW(thumbnail(img, 0, 1), std::invalid_argument);
}

TEST(ContactSheet, CellsHoldTheirPicturesAndLabels) {
  const SheetLayout l = sheet_layout(3, 100, 100);  // 3 cells of 100x100 in one row
  ASSERT_EQ(l.columns, 3u);
  ASSERT_EQ(l.cell_width, 100u);
  const Rgb8Image white = thumbnail(flat(100, 100, 1.f), 100, 100);
  const Rgb8Image grey = thumbnail(flat(100, 100, 0.2f), 100, 100);
  const Rgb8Image sheet = contact_sheet(l, {{7, &white}, {8, nullptr}, {-12, &grey}});
  ASSERT_EQ(sheet.width, l.width());
  const auto at = [&](uint32_t x, uint32_t y) {
    return sheet.rgb[(size_t{y} * sheet.width + x) * 3];
  };
  const uint32_t cell = l.cell_width + kSheetGap;
  EXPECT_EQ(at(0, 0), 16);                                   // the background between cells
  EXPECT_EQ(at(kSheetGap + 50, kSheetGap + 10), 255);        // frame 7's picture
  EXPECT_EQ(at(kSheetGap + cell + 50, kSheetGap + 10), 48);  // frame 8: none yet
  EXPECT_EQ(at(kSheetGap + 2 * cell + 50, kSheetGap + 10), grey.rgb[0]);
  // The label: a black box at the bottom left with white strokes in it ("7" is 3 digits' room
  // at scale 2: its top row is lit across).
  const uint32_t label_top = kSheetGap + l.cell_height - (5 * 2 + 2 * 2);
  EXPECT_EQ(at(kSheetGap, kSheetGap + l.cell_height - 1), 0);
  EXPECT_EQ(at(kSheetGap + 2, label_top + 2), 255);
  // "-12" is drawn on the grey cell: its minus sign's middle row is lit, the row above is not.
  const uint32_t x3 = kSheetGap + 2 * cell + 2;
  EXPECT_EQ(at(x3, label_top + 2 + 2 * 2), 255);
  EXPECT_EQ(at(x3, label_top + 2), 0);
  // A picture of the wrong size, too many cells: refused.
  const Rgb8Image small = thumbnail(flat(10, 10, 1.f), 10, 10);
  EXPECT_THROW(contact_sheet(l, {{1, &small}}), std::invalid_argument);
  EXPECT_THROW(contact_sheet(l, {{1, nullptr}, {2, nullptr}, {3, nullptr}, {4, nullptr}}),
               std::invalid_argument);
}

}  // namespace
}  // namespace rayfarm
