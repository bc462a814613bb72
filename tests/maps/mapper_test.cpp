#include "hmap/maps/mapper.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

Params test_params() {
  Params p = indoor_preset();
  p.map.cell_size = 0.1;
  p.map.point_distance_threshold = 0.15;
  p.map.min_range = 0.1;
  p.map.max_range = 20.0;
  p.map.min_hvoxel_height = 0.1;
  return p;
}

/// A room seen from (0, 0, 1): a wall at x = 8 (y in [-3, 3], z in [0, 2]) and a floor at z = 0,
/// with an optional pillar at x in [3.9, 4.1], y in [-0.3, 0.3], z in [0, 1.5] hiding what is
/// behind it. Points are in the sensor frame of an identity-rotation pose at `sensor`.
PointCloud room_scan(bool with_pillar, const Eigen::Vector3d& sensor, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  PointCloud pts;
  auto hidden = [&](const Eigen::Vector3d& p) {
    if (!with_pillar) return false;
    // The segment sensor -> p crosses the pillar's box?
    for (int s = 1; s < 200; ++s) {
      const Eigen::Vector3d q = sensor + (p - sensor) * (s / 200.0);
      if (q.x() > 3.9 && q.x() < 4.1 && std::abs(q.y()) < 0.3 && q.z() < 1.5) return true;
    }
    return false;
  };
  auto add = [&](const Eigen::Vector3d& p) {
    if (!hidden(p)) pts.emplace_back((p - sensor).cast<float>());
  };
  for (int k = 0; k < 6000; ++k) add({8.0, -3.0 + 6.0 * u(rng), 2.0 * u(rng)});          // wall
  for (int k = 0; k < 6000; ++k) add({1.0 + 7.0 * u(rng), -3.0 + 6.0 * u(rng), 0.0});    // floor
  if (with_pillar) {
    for (int k = 0; k < 1500; ++k) pts.emplace_back((Eigen::Vector3d(3.9, -0.3 + 0.6 * u(rng), 1.5 * u(rng)) - sensor).cast<float>());
  }
  return pts;
}

Pose at(const Eigen::Vector3d& t) {
  Pose T = Pose::Identity();
  T.translation() = t;
  return T;
}

TEST(MapperTest, EmptyScanLeavesMapEmpty) {
  Mapper m(test_params());
  const auto s = m.integrate({}, Pose::Identity());
  EXPECT_EQ(s.points_in, 0U);
  EXPECT_TRUE(m.map().empty());
  EXPECT_EQ(m.map().stats().hvoxels, 0U);
}

TEST(MapperTest, InvalidParametersAreRejected) {
  Params p = test_params();
  p.map.cell_size = -0.1;
  EXPECT_THROW(Mapper{p}, Error);
  p = test_params();
  p.map.cell_size = 1e-6;
  EXPECT_THROW(Mapper{p}, Error);
  p = test_params();
  p.map.max_range = 1e9;
  EXPECT_THROW(Mapper{p}, Error);
}

TEST(MapperTest, WallAndFloorAreMapped) {
  Mapper m(test_params());
  const Eigen::Vector3d sensor(0, 0, 1);
  const auto s = m.integrate(room_scan(false, sensor, 1), at(sensor));
  EXPECT_EQ(s.points_kept, s.points_in);
  EXPECT_GT(s.rays, 0U);
  EXPECT_TRUE(m.map().occupied(8.05, 0.0, 1.0));
  EXPECT_TRUE(m.map().occupied(5.05, 1.05, 0.0));
  EXPECT_FALSE(m.map().occupied(5.05, 1.05, 1.0));
  const MapStats st = m.map().stats();
  EXPECT_GT(st.cells, 1000U);
  EXPECT_GE(st.hvoxels, st.cells);
  EXPECT_GT(st.memory_bytes, st.hvoxels * sizeof(HVoxel));
  EXPECT_NEAR(st.bounds.max().x(), 8.1, 1e-6);
}

TEST(MapperTest, DynamicObjectIsCarvedOutOnceGone) {
  Mapper m(test_params());
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d sensor(0.02 * k, 0.0, 1.0);
    m.integrate(room_scan(true, sensor, 10 + k), at(sensor));
  }
  ASSERT_TRUE(m.map().occupied(3.95, 0.05, 1.0)) << "the pillar was mapped";
  ASSERT_TRUE(m.map().occupied(3.95, 0.05, 0.7));
  std::size_t removed = 0;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d sensor(0.02 * k, 0.01 * k, 1.0);
    removed += m.integrate(room_scan(false, sensor, 100 + k), at(sensor)).extrusion.removed;
  }
  EXPECT_GT(removed, 0U);
  EXPECT_FALSE(m.map().occupied(3.95, 0.05, 1.0)) << "the pillar is gone";
  EXPECT_FALSE(m.map().occupied(3.95, 0.05, 0.7));
  // The static scene stays.
  EXPECT_TRUE(m.map().occupied(8.05, 0.05, 1.0));
  EXPECT_TRUE(m.map().occupied(6.05, 1.05, 0.0));
}

TEST(MapperTest, WithoutFreeSpaceTheObjectStays) {
  Params p = test_params();
  p.map.free_space = FreeSpaceMode::kNone;
  Mapper m(p);
  m.integrate(room_scan(true, {0, 0, 1}, 1), at({0, 0, 1}));
  for (int k = 0; k < 5; ++k) m.integrate(room_scan(false, {0, 0, 1}, 2 + k), at({0, 0, 1}));
  EXPECT_TRUE(m.map().occupied(3.95, 0.05, 1.0));
}

/// `count` points spread over z in [z0, z1] at the centre of the cell (x, y), sensor at the origin.
PointCloud stack(double x, double y, double z0, double z1, int count) {
  PointCloud pts;
  for (int k = 0; k < count; ++k) pts.emplace_back(Point3f(static_cast<float>(x), static_cast<float>(y),
                                                          static_cast<float>(z0 + (z1 - z0) * k / (count - 1))));
  return pts;
}

// III-D: an HVoxel of a new scan joins the column's HVoxels it overlaps or comes closer to than
// the point-distance threshold; farther ones stay apart. (Merging with a gap of 0 kept the two
// near ones apart and passed every other test.)
TEST(MapperTest, ScansMergeWithinThePointDistanceThreshold) {
  Params p = test_params();  // d_pth 0.15 m, cells 0.1 m
  p.map.free_space = FreeSpaceMode::kNone;
  Mapper m(p);
  m.integrate(stack(5.05, 0.05, 0.00, 0.10, 20), Pose::Identity());
  m.integrate(stack(5.05, 0.05, 0.20, 0.30, 20), Pose::Identity());  // 0.10 m above: merged
  m.integrate(stack(5.05, 0.05, 0.60, 0.70, 20), Pose::Identity());  // 0.30 m above: apart
  const ColumnView c = m.map().column(5.05, 0.05);
  ASSERT_EQ(c.size(), 2U);
  EXPECT_FLOAT_EQ(c[0].z_min, 0.0F);
  EXPECT_FLOAT_EQ(c[0].z_max, 0.3F);
  EXPECT_FLOAT_EQ(c[1].z_min, 0.6F);
  EXPECT_FLOAT_EQ(c[1].z_max, 0.7F);
}

// III-D with map.ring_gap_slope: the join gap is the one the scan's cell was clustered with,
// max(0.15, 0.02 · d) at the cell's far corner's distance d from that scan's sensor. Cell (150, 0)
// seen from the origin: d = hypot(15.05, 0.05) + 0.0707 = 15.121, gap 0.302: an HVoxel 0.25 m
// above joins, one 0.35 m above stays apart. Seen from x = 10 (d = 5.121, gap 0.15) the 0.25 m
// does not join.
TEST(MapperTest, ScansMergeWithinTheRingGapOfTheirCell) {
  Params p = test_params();
  p.map.free_space = FreeSpaceMode::kNone;
  p.map.ring_gap_slope = 0.02;
  Pose from_10 = Pose::Identity();
  from_10.translation().x() = 10.0;
  const auto seen_from = [](PointCloud pts, double sensor_x) {
    for (Point3f& q : pts) q.x() -= static_cast<float>(sensor_x);
    return pts;
  };
  Mapper far(p);
  far.integrate(stack(15.05, 0.05, 0.00, 0.10, 20), Pose::Identity());
  far.integrate(stack(15.05, 0.05, 0.35, 0.45, 20), Pose::Identity());  // 0.25 m above: joined
  far.integrate(stack(15.05, 0.05, 0.80, 0.90, 20), Pose::Identity());  // 0.35 m above: apart
  const ColumnView c = far.map().column(15.05, 0.05);
  ASSERT_EQ(c.size(), 2U);
  EXPECT_FLOAT_EQ(c[0].z_min, 0.0F);
  EXPECT_FLOAT_EQ(c[0].z_max, 0.45F);
  EXPECT_FLOAT_EQ(c[1].z_min, 0.8F);
  Mapper near(p);
  near.integrate(stack(15.05, 0.05, 0.00, 0.10, 20), Pose::Identity());
  near.integrate(seen_from(stack(15.05, 0.05, 0.35, 0.45, 20), 10.0), from_10);
  ASSERT_EQ(near.map().column(15.05, 0.05).size(), 2U);
  // Without the slope, the threshold alone: apart from the origin too.
  p.map.ring_gap_slope = 0.0;
  Mapper fixed(p);
  fixed.integrate(stack(15.05, 0.05, 0.00, 0.10, 20), Pose::Identity());
  fixed.integrate(stack(15.05, 0.05, 0.35, 0.45, 20), Pose::Identity());
  EXPECT_EQ(fixed.map().column(15.05, 0.05).size(), 2U);
}

// III-E within one scan: a hit outranks a pass-through. Rays to a wall 8 m away pass through the
// cell of a thin pole 4 m away at the pole's heights; the pole stays, however often it is seen so.
TEST(MapperTest, AScansOwnRaysDoNotCarveItsOwnHits) {
  Mapper m(test_params());
  PointCloud scan = stack(4.05, 0.05, -0.8, 0.8, 40);  // the pole, sensor at z = 1 above the floor
  for (int k = 0; k < 400; ++k) {
    const double y = 0.01 + 0.08 * (k % 20) / 19.0;      // behind the pole's cell, as seen from the sensor
    const double z = -0.6 + 1.2 * (k / 20) / 19.0;
    for (const Point3f& q : stack(8.0, 2.0 * y, 2.0 * z, 2.0 * z, 2)) scan.push_back(q);
  }
  for (int k = 0; k < 6; ++k) m.integrate(scan, at({0, 0, 0}));
  const ColumnView c = m.map().column(4.05, 0.05);
  ASSERT_EQ(c.size(), 1U);
  EXPECT_FLOAT_EQ(c[0].z_min, -0.8F);
  EXPECT_FLOAT_EQ(c[0].z_max, 0.8F);
}

TEST(MapperTest, ColumnsStayValidAndRecoveryCoversHVoxels) {
  Mapper m(test_params());
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d sensor(0.1 * k, -0.05 * k, 1.0);
    m.integrate(room_scan(k < 2, sensor, 50 + k), at(sensor));
  }
  std::size_t hvoxels = 0;
  m.map().for_each_column([&](const CellKey&, const ColumnView& c) {
    EXPECT_TRUE(c.is_valid());
    hvoxels += c.size();
  });
  const PointCloud pts = recover_points(m.map(), 0.05);
  EXPECT_GE(pts.size(), hvoxels);
  for (std::size_t k = 0; k < pts.size(); k += 97) {
    EXPECT_TRUE(m.map().occupied(pts[k].x(), pts[k].y(), pts[k].z()));
  }
}

// The scan's cells are merged tile by tile, but the tiles the map lacks are made in the order the
// scan first reaches them (what a lookup per cell did): the map's tile order, which its exports
// and walks follow, does not depend on where the tiles lie in the scan window.
TEST(MapperTest, NewTilesAreMadeInTheOrderTheScanFirstReachesThem) {
  Params p = test_params();
  p.map.free_space = FreeSpaceMode::kNone;
  Mapper m(p);
  // Cells of 0.1 m, tiles of 8 cells (0.8 m). Listed against the window's row order: the last
  // tile in it first, one of its cells again at the end.
  const PointCloud points{{5.05F, 5.05F, 0.0F}, {0.55F, -3.05F, 0.0F}, {-2.05F, 2.05F, 0.5F},
                          {0.55F, -3.05F, 1.0F}, {5.15F, 5.05F, 0.0F}};
  const auto stats = m.integrate(points, Pose::Identity());
  EXPECT_EQ(stats.scan_cells, 4U);
  std::vector<CellKey> order;
  m.map().for_each_tile([&](const CellKey& key, const HMap::Tile&) { order.push_back(key); });
  ASSERT_EQ(order.size(), 3U);
  EXPECT_EQ(order[0], (CellKey{6, 6}));
  EXPECT_EQ(order[1], (CellKey{0, -4}));
  EXPECT_EQ(order[2], (CellKey{-3, 2}));
  // Every point's cell holds it: (0.55, -3.05) twice, 1 m apart (two HVoxels).
  EXPECT_EQ(m.map().column(0.55, -3.05).size(), 2U);
  EXPECT_EQ(m.map().column(5.05, 5.05).size(), 1U);
  EXPECT_EQ(m.map().column(5.15, 5.05).size(), 1U);
  EXPECT_EQ(m.map().column(-2.05, 2.05).size(), 1U);
  EXPECT_EQ(m.map().column(-2.15, 2.05).size(), 0U);
}

}  // namespace
}  // namespace hmap
