#include "hmap/occupancy/occupancy_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

TEST(OccupancyGridTest, UnknownUntilObserved) {
  OccupancyGrid g(0.1, 0.12, 0.97);
  EXPECT_FALSE(g.probability_at({0, 0}).has_value());
  EXPECT_EQ(g.known_cells(), 0U);
  g.update({-3, 7}, 0.0F);
  ASSERT_TRUE(g.probability_at({-3, 7}).has_value());
  EXPECT_DOUBLE_EQ(*g.probability_at({-3, 7}), 0.5);  // observed, no evidence either way
  EXPECT_FALSE(g.probability_at({-3, 6}).has_value());
  EXPECT_EQ(g.known_cells(), 1U);
}

TEST(OccupancyGridTest, LogOddsAddAndClamp) {
  OccupancyGrid g(0.1, 0.12, 0.97);
  const float hit = log_odds(0.7);
  g.update({1, 1}, hit);
  g.update({1, 1}, hit);
  // eq. (3): two hits of 0.7 give log(0.7/0.3) * 2.
  EXPECT_NEAR(*g.log_odds_at({1, 1}), 2.0 * std::log(0.7 / 0.3), 1e-6);
  for (int k = 0; k < 50; ++k) g.update({1, 1}, hit);
  EXPECT_NEAR(*g.probability_at({1, 1}), 0.97, 1e-6);  // clamped as OctoMap clamps
  for (int k = 0; k < 100; ++k) g.update({1, 1}, log_odds(0.3));
  EXPECT_NEAR(*g.probability_at({1, 1}), 0.12, 1e-6);
}

TEST(OccupancyGridTest, ForEachVisitsObservedCellsWithTheirKeys) {
  OccupancyGrid g(0.25, 0.12, 0.97);
  const std::vector<CellKey> keys = {{0, 0}, {-1, -1}, {8, -9}, {100, 3}};
  for (const auto& k : keys) g.update(k, 0.5F);
  std::vector<CellKey> seen;
  g.for_each_cell([&](const CellKey& k, float l) {
    seen.push_back(k);
    EXPECT_FLOAT_EQ(l, 0.5F);
  });
  EXPECT_EQ(seen.size(), keys.size());
  for (const auto& k : keys) EXPECT_NE(std::find(seen.begin(), seen.end(), k), seen.end());
}

TEST(OccupancyGridTest, BadParametersAreRejected) {
  EXPECT_THROW(OccupancyGrid(0.0, 0.12, 0.97), Error);
  EXPECT_THROW(OccupancyGrid(0.1, 0.6, 0.97), Error);
  EXPECT_THROW(OccupancyGrid(0.1, 0.12, 1.0), Error);
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

TEST(OccupancyGridTest, MoreOccupiedTakesTheLargerLogOddsCellByCell) {
  OccupancyGrid a(0.1, 0.12, 0.97);
  OccupancyGrid b(0.1, 0.12, 0.97);
  a.set({0, 0}, -1.0F);  // free in a, occupied in b
  b.set({0, 0}, 2.0F);
  a.set({1, 0}, 1.5F);   // occupied in a, free in b
  b.set({1, 0}, -1.5F);
  a.set({-9, 4}, -0.5F);  // known to one grid only
  b.set({20, -3}, 0.25F);
  const OccupancyGrid c = more_occupied(a, b);
  EXPECT_EQ(c.known_cells(), 4U);
  EXPECT_FLOAT_EQ(*c.log_odds_at({0, 0}), 2.0F);
  EXPECT_FLOAT_EQ(*c.log_odds_at({1, 0}), 1.5F);
  EXPECT_FLOAT_EQ(*c.log_odds_at({-9, 4}), -0.5F);
  EXPECT_FLOAT_EQ(*c.log_odds_at({20, -3}), 0.25F);
  EXPECT_FALSE(c.log_odds_at({5, 5}).has_value());
  // Empty with empty is empty; different cells are refused.
  EXPECT_EQ(more_occupied(OccupancyGrid(0.1, 0.12, 0.97), OccupancyGrid(0.1, 0.12, 0.97)).known_cells(), 0U);
  EXPECT_THROW((void)more_occupied(a, OccupancyGrid(0.2, 0.12, 0.97)), Error);
}

TEST(GridRasterTest, CoversTheObservedCellsBoundingBox) {
  OccupancyGrid g(0.5, 0.12, 0.97);
  g.set({-3, 2}, log_odds(0.8));
  g.set({1, 4}, log_odds(0.2));
  const GridRaster r = raster(g);
  EXPECT_EQ(r.i_min, -3);
  EXPECT_EQ(r.j_min, 2);
  EXPECT_EQ(r.width, 5);   // i = -3 .. 1
  EXPECT_EQ(r.height, 3);  // j = 2 .. 4
  EXPECT_DOUBLE_EQ(r.cell_size, 0.5);
  ASSERT_EQ(r.probability.size(), 15U);
  EXPECT_NEAR(r.probability[0], 0.8, 1e-6);                 // (col 0, row 0): key (-3, 2)
  EXPECT_NEAR(r.probability[2 * 5 + 4], 0.2, 1e-6);         // (col 4, row 2): key (1, 4)
  int unknown = 0;
  for (float p : r.probability) unknown += std::isnan(p) ? 1 : 0;
  EXPECT_EQ(unknown, 13);
}

TEST(GridRasterTest, EmptyGridGivesAnEmptyRasterAndAHugeSpanIsRefused) {
  OccupancyGrid g(0.1, 0.12, 0.97);
  const GridRaster empty = raster(g);
  EXPECT_EQ(empty.width, 0);
  EXPECT_EQ(empty.height, 0);
  EXPECT_TRUE(empty.probability.empty());
  g.set({0, 0}, 0.0F);
  g.set({100000, 100000}, 0.0F);  // two cells 10 km apart: 10^10 cells
  try {
    (void)raster(g);
    FAIL() << "a 100001 x 100001 raster was made";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("span 100001 x 100001 cells"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hmap
