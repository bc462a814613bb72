#pragma once
// Two HMAPs hold the same columns: every non-empty column of one equals the other's at the same
// cell, HVoxel for HVoxel, and both hold as many (tile order and empty tiles aside).

#include <gtest/gtest.h>

#include "hmap/maps/hmap.hpp"

namespace hmap::test {

inline void expect_same_columns(const HMap& a, const HMap& b) {
  std::size_t n = 0;
  a.for_each_column([&](const CellKey& k, const ColumnView& c) {
    ++n;
    const ColumnView o = b.column(k);
    ASSERT_EQ(o.size(), c.size()) << k.i << "," << k.j;
    for (std::size_t q = 0; q < c.size(); ++q) EXPECT_EQ(o[q], c[q]) << k.i << "," << k.j;
  });
  EXPECT_EQ(n, b.stats().cells);
}

}  // namespace hmap::test
