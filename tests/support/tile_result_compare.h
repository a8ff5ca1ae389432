#pragma once
// One unit's result equal to another in every field: rect, samples, both fixed-point sums bit for
// bit, and the counts.
#include <gtest/gtest.h>

#include "common/image/film.h"

namespace rayfarm::testing {

inline void expect_same_result(const TileResult& got, const TileResult& want) {
  EXPECT_EQ(got.rect, want.rect);
  EXPECT_EQ(got.samples, want.samples);
  EXPECT_TRUE(got.sum == want.sum) << "sums differ";
  EXPECT_TRUE(got.sum_sq == want.sum_sq) << "squared sums differ";
  EXPECT_EQ(got.nonfinite, want.nonfinite);
  EXPECT_EQ(got.rays, want.rays);
}

}  // namespace rayfarm::testing
