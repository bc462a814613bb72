#include "hmap/maps/cell_centroids.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <utility>
#include <limits>
#include <numbers>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

/// Two cells' HVoxels with their centroids set by hand (level frame, 0.5 m cells).
ScanHVoxels hand_scan() {
  ScanHVoxels s;
  s.cells = {{{0, 0}, 0, 2}, {{3, -1}, 2, 1}};
  s.hvoxels = {{0.0F, 0.1F, 4.0F, 0.5F},    // thin: left out
               {0.5F, 2.5F, 3.0F, 0.5F},    // tall, 3 points at (0.1, 0.4)
               {0.0F, 1.0F, 1.0F, 0.5F}};   // tall, 1 point at (1.7, -0.3)
  s.centroids = {{0.25F, 0.25F}, {0.1F, 0.4F}, {1.7F, -0.3F}};
  return s;
}

// By hand: moved by (10, 20) and turned 90°, (0.1, 0.4) goes to (9.6, 20.1), cell (19, 40) of
// 0.5 m, centre (9.75, 20.25): offset (−0.15, −0.15); (1.7, −0.3) to (10.3, 21.7), cell (20, 43),
// centre (10.25, 21.75): offset (0.05, −0.05). A second scan into the first cell weighs by points.
TEST(CellCentroids, OffsetsByHand) {
  CellCentroids c(0.5);
  const ScanHVoxels scan = hand_scan();
  c.add(scan, 10.0, 20.0, std::numbers::pi / 2.0, 0.3F);
  ASSERT_EQ(c.size(), 2U);
  const Eigen::Vector2f* a = c.offset({19, 40});
  const Eigen::Vector2f* b = c.offset({20, 43});
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_NEAR(a->x(), -0.15, 1e-5);
  EXPECT_NEAR(a->y(), -0.15, 1e-5);
  EXPECT_NEAR(b->x(), 0.05, 1e-5);
  EXPECT_NEAR(b->y(), -0.05, 1e-5);
  EXPECT_EQ(c.offset({0, 0}), nullptr) << "the thin HVoxel's cell, and the level frame's, hold nothing";
  // One point more at (9.9, 20.4) in the same cell: (3·(9.6, 20.1) + (9.9, 20.4)) / 4 = (9.675, 20.175).
  ScanHVoxels one;
  one.cells = {{{0, 0}, 0, 1}};
  one.hvoxels = {{0.0F, 1.0F, 1.0F, 0.5F}};
  one.centroids = {{9.9F, 20.4F}};
  c.add(one, 0.0, 0.0, 0.0, 0.3F);
  EXPECT_NEAR(c.offset({19, 40})->x(), 9.675 - 9.75, 1e-5);
  EXPECT_NEAR(c.offset({19, 40})->y(), 20.175 - 20.25, 1e-5);
}

// By hand: a centroid 0.05, −0.02 m from the centre of cell (0, 0) of 0.25 m, at (0.175, 0.105),
// weight 3, moved by (1, 2) and turned 90°: (1 − 0.105, 2 + 0.175) = (0.895, 2.175), cell (3, 8),
// centre (0.875, 2.125), offset (0.02, 0.05). Into a cell holding (0.9, 2.2) with weight 1:
// (3·(0.895, 2.175) + (0.9, 2.2)) / 4 = (0.89625, 2.18125).
TEST(CellCentroids, AnotherMapsCentroidsAddedMovedByItsPose) {
  CellCentroids other(0.25);
  other.restore({0, 0}, {0.05F, -0.02F}, 3.0);
  CellCentroids c(0.25);
  c.add(other, 1.0, 2.0, std::numbers::pi / 2.0);
  ASSERT_EQ(c.size(), 1U);
  ASSERT_NE(c.offset({3, 8}), nullptr);
  EXPECT_NEAR(c.offset({3, 8})->x(), 0.02, 1e-6);
  EXPECT_NEAR(c.offset({3, 8})->y(), 0.05, 1e-6);
  CellCentroids d(0.25);
  d.add(0.9, 2.2, 1.0);
  d.add(other, 1.0, 2.0, std::numbers::pi / 2.0);
  ASSERT_EQ(d.size(), 1U);
  EXPECT_NEAR(d.offset({3, 8})->x(), 0.89625 - 0.875, 1e-6);
  EXPECT_NEAR(d.offset({3, 8})->y(), 2.18125 - 2.125, 1e-6);
  // Into itself: the same offsets, each weight doubled.
  d.add(d, 0.0, 0.0, 0.0);
  EXPECT_EQ(d.size(), 1U);
  EXPECT_NEAR(d.offset({3, 8})->x(), 0.89625 - 0.875, 1e-6);
  d.for_each([](const CellKey&, const Eigen::Vector2f&, double w) { EXPECT_DOUBLE_EQ(w, 8.0); });
  EXPECT_THROW(c.add(CellCentroids(0.5), 0.0, 0.0, 0.0), Error);
}

TEST(CellCentroids, AScanWithoutCentroidsAddsNothingAndABadCellIsRefused) {
  CellCentroids c(0.2);
  ScanHVoxels scan = hand_scan();
  scan.centroids.clear();
  c.add(scan, 0.0, 0.0, 0.0, 0.0F);
  EXPECT_EQ(c.size(), 0U);
  for (const double bad : {0.0, -0.1, std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(CellCentroids{bad}, Error) << bad;
  }
}

// The tiles hold what a hash map of cells would: random points over cells of every sign (tiles
// cut at negative keys too), each cell's offset checked against a brute-force mean, and the view
// over a window answers as the index does inside it, outside it, and for a tile made after reset.
TEST(CellCentroids, TilesAndTheirViewAgreeWithABruteForceTwin) {
  const double cell = 0.2;
  CellCentroids c(cell);
  std::map<std::pair<std::int32_t, std::int32_t>, Eigen::Vector3d> twin;  // Σ w·x, Σ w·y, Σ w
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(-3.0, 3.0);
  std::uniform_real_distribution<double> weight(0.5, 4.0);
  for (int k = 0; k < 4000; ++k) {
    const double x = pos(rng);
    const double y = pos(rng);
    const double w = weight(rng);
    c.add(x, y, w);
    const std::pair<std::int32_t, std::int32_t> key{static_cast<std::int32_t>(std::floor(x / cell)),
                                                    static_cast<std::int32_t>(std::floor(y / cell))};
    twin.try_emplace(key, Eigen::Vector3d::Zero()).first->second += Eigen::Vector3d(w * x, w * y, w);
  }
  c.add(1.0, 1.0, 0.0);  // no weight, no position: nothing
  c.add(std::nan(""), 1.0, 1.0);
  c.add(1.0, std::numeric_limits<double>::infinity(), 1.0);
  ASSERT_EQ(c.size(), twin.size());
  CellCentroids::View view;
  view.reset(&c, {0, 0}, 6);  // tiles of cells −6..6: [−8, 8) in both axes
  std::size_t inside = 0;
  for (std::int32_t i = -16; i < 16; ++i) {
    for (std::int32_t j = -16; j < 16; ++j) {
      const auto it = twin.find({i, j});
      const Eigen::Vector2f* got = c.offset({i, j});
      ASSERT_EQ(view.offset({i, j}), got) << i << "," << j;
      inside += std::abs(i) <= 6 && std::abs(j) <= 6 && got != nullptr ? 1U : 0U;
      if (it == twin.end()) {
        EXPECT_EQ(got, nullptr) << i << "," << j;
        continue;
      }
      ASSERT_NE(got, nullptr) << i << "," << j;
      const Eigen::Vector3d& t = it->second;
      EXPECT_NEAR(got->x(), t.x() / t.z() - (i + 0.5) * cell, 1e-6) << i << "," << j;
      EXPECT_NEAR(got->y(), t.y() / t.z() - (j + 0.5) * cell, 1e-6) << i << "," << j;
      EXPECT_LE(std::abs(got->x()), 0.5 * cell + 1e-6);
      EXPECT_LE(std::abs(got->y()), 0.5 * cell + 1e-6);
    }
  }
  EXPECT_GT(inside, 100U);
  // A tile made after the view: found through the index.
  c.add(30.05, -30.05, 1.0);
  const Eigen::Vector2f* late = view.offset({150, -151});
  ASSERT_NE(late, nullptr);
  EXPECT_NEAR(late->x(), 30.05 - 150.5 * cell, 1e-5);
  EXPECT_NEAR(late->y(), -30.05 + 150.5 * cell, 1e-5);
  // A view of nothing answers nothing.
  CellCentroids::View none;
  none.reset(nullptr, {0, 0}, 6);
  EXPECT_EQ(none.offset({0, 0}), nullptr);
  EXPECT_GT(c.bytes(), c.size() * 8U);
}

}  // namespace
}  // namespace hmap
