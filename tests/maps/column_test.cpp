#include "hmap/maps/column.hpp"

#include "hmap/core/error.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace hmap {
namespace {

MapParams params() { return outdoor_preset().map; }

HVoxel hv(float lo, float hi, float count) {
  HVoxel v{lo, hi, count, 0.0F};
  update_density(v, params());
  return v;
}

TEST(ColumnTest, EmptyColumnFindsNothing) {
  Column c;
  EXPECT_TRUE(c.empty());
  EXPECT_EQ(c.find(0.0F), nullptr);
  EXPECT_EQ(c.lower_bound(0.0F), 0U);
  EXPECT_TRUE(c.is_valid());
  EXPECT_EQ(c.heap_bytes(), 0U);
}

TEST(ColumnTest, MergeDisjointKeepsOrder) {
  Column c;
  c.merge(hv(2.0F, 2.5F, 3), 0.4F, params());
  c.merge(hv(0.0F, 0.1F, 3), 0.4F, params());
  c.merge(hv(1.0F, 1.2F, 3), 0.4F, params());
  ASSERT_EQ(c.size(), 3U);
  EXPECT_FLOAT_EQ(c[0].z_min, 0.0F);
  EXPECT_FLOAT_EQ(c[1].z_min, 1.0F);
  EXPECT_FLOAT_EQ(c[2].z_min, 2.0F);
  EXPECT_TRUE(c.is_valid());
  EXPECT_GT(c.heap_bytes(), 0U);
}

TEST(ColumnTest, MergeUnitesOverlapAndGapWithinThreshold) {
  Column c;
  c.merge(hv(0.0F, 1.0F, 10), 0.4F, params());
  c.merge(hv(2.0F, 3.0F, 20), 0.4F, params());
  // Bridges both: gap 1.0 -> 1.3 is 0.3 <= 0.4, and 1.7 -> 2.0 is 0.3 <= 0.4.
  c.merge(hv(1.3F, 1.7F, 5), 0.4F, params());
  ASSERT_EQ(c.size(), 1U);
  EXPECT_FLOAT_EQ(c[0].z_min, 0.0F);
  EXPECT_FLOAT_EQ(c[0].z_max, 3.0F);
  EXPECT_FLOAT_EQ(c[0].count, 35.0F);
  EXPECT_FLOAT_EQ(c[0].density, hvoxel_density(35.0, 3.0, params()));
}

TEST(ColumnTest, MergeJustBeyondThresholdStaysApart) {
  Column c;
  c.merge(hv(0.0F, 1.0F, 10), 0.4F, params());
  c.merge(hv(1.41F, 2.0F, 10), 0.4F, params());
  EXPECT_EQ(c.size(), 2U);
}

TEST(ColumnTest, FindMatchesLinearScan) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> z(-5.0F, 5.0F);
  Column c;
  for (int k = 0; k < 40; ++k) {
    const float a = z(rng);
    c.merge(hv(a, a + 0.05F, 1), 0.0F, params());
  }
  ASSERT_TRUE(c.is_valid());
  for (int k = 0; k < 2000; ++k) {
    const float q = z(rng);
    const HVoxel* brute = nullptr;
    for (const HVoxel& v : c)
      if (v.z_min <= q && q <= v.z_max) brute = &v;
    EXPECT_EQ(c.find(q), brute) << "z = " << q;
  }
}

TEST(ColumnTest, CopyAndMoveKeepContents) {
  Column c;
  c.merge(hv(0.0F, 0.1F, 3), 0.0F, params());
  c.merge(hv(1.0F, 1.1F, 3), 0.0F, params());
  Column copy(c);
  Column moved(std::move(c));
  ASSERT_EQ(copy.size(), 2U);
  ASSERT_EQ(moved.size(), 2U);
  EXPECT_EQ(copy[1], moved[1]);
  Column assigned;
  assigned = copy;
  EXPECT_EQ(assigned[0], copy[0]);
}

// The packed tile against 64 standalone columns given the same random edits: merges, erases,
// inserts at the top, clears; every column and the totals must agree after every step.
TEST(ColumnTileTest, MatchesStandaloneColumnsUnderRandomEdits) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> cell(0, ColumnTile::kCells - 1);
  std::uniform_int_distribution<int> op(0, 9);
  std::uniform_real_distribution<float> z(-3.0F, 3.0F);
  ColumnTile tile;
  std::vector<Column> twin(ColumnTile::kCells);
  EXPECT_TRUE(tile.empty());
  EXPECT_EQ(tile.heap_bytes(), 0U);
  for (int step = 0; step < 20000; ++step) {
    const int local = cell(rng);
    TileColumn column(tile, local);
    Column& expected = twin[static_cast<std::size_t>(local)];
    const int o = op(rng);
    if (o < 7) {
      const float a = z(rng);
      const HVoxel v = hv(a, a + 0.1F, 2);
      column.merge(v, 0.05F, params());
      expected.merge(v, 0.05F, params());
    } else if (o < 9 && !expected.empty()) {
      const std::size_t first = std::uniform_int_distribution<std::size_t>(0, expected.size() - 1)(rng);
      column.erase(first, first + 1);
      expected.erase(first, first + 1);
    } else if (o == 9 && step % 7 == 0) {
      column.clear();
      expected.clear();
    }
    ASSERT_EQ(column.size(), expected.size()) << "step " << step;
    ASSERT_TRUE(std::equal(column.begin(), column.end(), expected.begin())) << "step " << step;
  }
  std::size_t total = 0;
  for (int local = 0; local < ColumnTile::kCells; ++local) {
    const ColumnView c = tile.column(local);
    const Column& e = twin[static_cast<std::size_t>(local)];
    ASSERT_EQ(c.size(), e.size());
    EXPECT_TRUE(std::equal(c.begin(), c.end(), e.begin()));
    EXPECT_TRUE(c.is_valid());
    total += e.size();
  }
  EXPECT_EQ(tile.hvoxel_count(), total);
  EXPECT_GE(tile.heap_bytes(), total * sizeof(HVoxel));
  // A copy holds the same columns; shrinking keeps them and fits the buffer; a moved-from tile
  // is empty, not a tile with columns and no buffer.
  ColumnTile copy(tile);
  {
    ColumnTile source(tile);
    ColumnTile target(std::move(source));
    EXPECT_TRUE(source.empty());  // NOLINT(bugprone-use-after-move): what is left is specified
    EXPECT_EQ(source.heap_bytes(), 0U);
    EXPECT_TRUE(source.column(3).empty());
    EXPECT_EQ(target.hvoxel_count(), total);
  }
  copy.shrink_to_fit();
  EXPECT_EQ(copy.heap_bytes(), total * sizeof(HVoxel) + 16);
  for (int local = 0; local < ColumnTile::kCells; ++local) {
    EXPECT_TRUE(std::equal(copy.column(local).begin(), copy.column(local).end(), tile.column(local).begin()));
  }
}

// Past 65,535 HVoxels the 16-bit offsets would wrap: the tile moves to 32-bit offsets and every
// column stays intact; shrinking below the limit moves it back.
TEST(ColumnTileTest, GrowsPastSixteenBitOffsets) {
  ColumnTile tile;
  EXPECT_TRUE(tile.column(5).empty());
  EXPECT_EQ(tile.column(5).find(0.0F), nullptr);
  const auto hv_at = [](std::size_t k) { return HVoxel{float(2 * k), float(2 * k) + 0.5F, 1, 0.1F}; };
  TileColumn first(tile, 0);
  TileColumn middle(tile, 30);
  TileColumn last(tile, ColumnTile::kCells - 1);
  constexpr std::size_t kPer = 30000;  // three columns of 30,000: 90,000 in the tile
  constexpr std::size_t kShifted = 100;  // the middle column's lowest, inserted last at the bottom
  for (std::size_t k = 0; k < kPer; ++k) first.push_back(hv_at(k));
  for (std::size_t k = kShifted; k < kPer; ++k) middle.push_back(hv_at(k));
  for (std::size_t k = 0; k < kPer; ++k) last.push_back(hv_at(k));  // crosses 65,535 here
  for (std::size_t k = kShifted; k-- > 0;) middle.insert(0, hv_at(k));  // shifts the last column
  ASSERT_EQ(tile.hvoxel_count(), 3 * kPer);
  for (const int local : {0, 30, ColumnTile::kCells - 1}) {
    const ColumnView c = tile.column(local);
    ASSERT_EQ(c.size(), kPer) << local;
    EXPECT_TRUE(c.is_valid()) << local;
    for (const std::size_t k : {std::size_t{0}, std::size_t{1}, kPer / 2, kPer - 1}) EXPECT_EQ(c[k], hv_at(k)) << local;
  }
  EXPECT_TRUE(tile.column(1).empty());
  EXPECT_TRUE(tile.column(63 - 1).empty());
  EXPECT_GT(tile.heap_bytes(), 3 * kPer * sizeof(HVoxel) + (ColumnTile::kCells + 1) * 4);
  const ColumnTile copy(tile);
  EXPECT_TRUE(std::equal(copy.column(30).begin(), copy.column(30).end(), tile.column(30).begin()));

  // Back under the limit: the same columns, 16-bit offsets again, the buffer fitted.
  middle.erase(0, kPer);
  last.erase(kPer / 2, kPer);
  tile.shrink_to_fit();
  EXPECT_EQ(tile.hvoxel_count(), kPer + kPer / 2);
  EXPECT_EQ(tile.heap_bytes(), (kPer + kPer / 2) * sizeof(HVoxel) + 16);
  EXPECT_TRUE(tile.column(30).empty());
  ASSERT_EQ(tile.column(ColumnTile::kCells - 1).size(), kPer / 2);
  EXPECT_EQ(tile.column(ColumnTile::kCells - 1)[kPer / 2 - 1], hv_at(kPer / 2 - 1));
  EXPECT_EQ(tile.column(0)[kPer - 1], hv_at(kPer - 1));
  first.push_back(hv_at(kPer));
  EXPECT_EQ(tile.column(0).size(), kPer + 1);
}

TEST(DensityTest, EquationOneByHand) {
  MapParams p = params();  // K_m = 1, K_n = 0.0005, d_min = 5, cell 0.25 m, h floor 0.25 m
  // |v| = d_min gives exactly K_m / 2 whatever the volume.
  EXPECT_FLOAT_EQ(hvoxel_density(5, 1.0, p), 0.5F);
  // |v| = 105, h = 2 m: V = 2 * 0.0625 = 0.125; x = 0.0005 * 100 / 0.125 = 0.4.
  EXPECT_NEAR(hvoxel_density(105, 2.0, p), 1.0 / (1.0 + std::exp(-0.4)), 1e-6);
  // One point: h = 0 is floored at 0.25 m: V = 0.015625, x = 0.0005 * -4 / 0.015625 = -0.128.
  EXPECT_NEAR(hvoxel_density(1, 0.0, p), 1.0 / (1.0 + std::exp(0.128)), 1e-6);
  p.density_gain = 2.0;
  EXPECT_FLOAT_EQ(hvoxel_density(5, 1.0, p), 1.0F);
}

}  // namespace
}  // namespace hmap
