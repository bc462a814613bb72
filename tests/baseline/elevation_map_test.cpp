#include "hmap/baseline/elevation_map.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

Params params(double cell) {
  Params p;
  p.map.cell_size = cell;
  return p;
}

TEST(ElevationMapTest, UnknownUntilWritten) {
  ElevationMap map(params(0.25));
  EXPECT_TRUE(map.empty());
  EXPECT_EQ(map.find(CellKey{0, 0}), nullptr);
  EXPECT_FALSE(map.elevation_at(0.1, 0.1));
  ElevationCell& c = map.cell_for_update({3, -2});
  EXPECT_FALSE(c.known());
  EXPECT_TRUE(std::isnan(c.elevation));
  // A touched tile does not make its cells known.
  EXPECT_EQ(map.find(CellKey{3, -2}), nullptr);
  EXPECT_EQ(map.known_cells(), 0U);
  c = {0.5F, 0.01F, 0.4F, 3};
  ASSERT_NE(map.find(CellKey{3, -2}), nullptr);
  EXPECT_DOUBLE_EQ(*map.elevation_at(0.8, -0.3), 0.5F);  // floor(0.8 / 0.25) = 3, floor(−0.3 / 0.25) = −2
  EXPECT_FALSE(map.elevation_at(0.8, -0.6));            // a neighbour in the same tile
  EXPECT_EQ(map.known_cells(), 1U);
  EXPECT_EQ(map.tiles(), 1U);
}

TEST(ElevationMapTest, KeysLikeTheHMap) {
  const ElevationMap map(params(0.25));
  EXPECT_EQ(*map.key_of(-0.01, 0.26), (CellKey{-1, 1}));
  EXPECT_FALSE(map.key_of(std::nan(""), 0.0));
  EXPECT_FALSE(map.key_of(1e12, 0.0));  // beyond 2^30 cells
  EXPECT_TRUE(map.cell_center({-1, 1}).isApprox(Eigen::Vector2d(-0.125, 0.375)));
}

TEST(ElevationMapTest, MemoryAndStats) {
  ElevationMap map(params(0.5));
  EXPECT_EQ(map.memory_bytes(), 0U);
  map.cell_for_update({0, 0}) = {1.0F, 0.01F, 1.0F, 1};
  map.cell_for_update({1, 7}) = {2.0F, 0.01F, 1.5F, 1};       // same tile
  map.cell_for_update({-200, 9}) = {-1.0F, 0.01F, -1.0F, 1};  // another
  EXPECT_EQ(sizeof(ElevationCell), 16U);
  const ElevationMapStats s = map.stats();
  EXPECT_EQ(s.cells, 3U);
  EXPECT_EQ(s.tiles, 2U);
  EXPECT_EQ(s.memory_bytes, map.memory_bytes());
  EXPECT_GE(s.memory_bytes, 2 * sizeof(ElevationMap::Tile));
  EXPECT_DOUBLE_EQ(s.bounds.min().x(), -100.0);
  EXPECT_DOUBLE_EQ(s.bounds.max().y(), 5.0);
  EXPECT_DOUBLE_EQ(s.bounds.min().z(), -1.0);
  EXPECT_DOUBLE_EQ(s.bounds.max().z(), 2.0);
  map.clear();
  EXPECT_TRUE(map.empty());
  EXPECT_TRUE(map.stats().bounds.isEmpty());
}

TEST(ElevationMapTest, RejectsBadParameters) {
  EXPECT_THROW(ElevationMap(params(0.0)), Error);
  EXPECT_THROW(ElevationMap(params(-1.0)), Error);
}

}  // namespace
}  // namespace hmap
