#include "hmap/maps/scan_hvoxels.hpp"

#include "hmap/core/error.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <vector>

namespace hmap {
namespace {

MapParams unit_params() {
  MapParams p;
  p.cell_size = 1.0;
  p.point_distance_threshold = 0.5;
  p.min_range = 0.0;
  p.max_range = 10.0;
  p.min_hvoxel_height = 0.1;
  return p;
}

TEST(ScanHVoxelsTest, EmptyCloudGivesEmptyRepresentation) {
  ScanHVoxelizer h(unit_params());
  ScanHVoxels r;
  h.build({}, Pose::Identity(), r);
  EXPECT_TRUE(r.cells.empty());
  EXPECT_TRUE(r.hvoxels.empty());
  EXPECT_EQ(r.points_in, 0U);
}

// Alg. 1 + 2 by hand: cell (2, 0) gets heights {0, 0.2, 0.4, 1.5, 1.9}: gap 0.4 -> 1.5 is 1.1
// > 0.5, so two clusters [0, 0.4] (3 points) and [1.5, 1.9] (2 points); cell (-1, 3) one point.
TEST(ScanHVoxelsTest, IndexingAndClusteringByHand) {
  ScanHVoxelizer h(unit_params());
  ScanHVoxels r;
  PointCloud pts = {{2.5F, 0.5F, 0.4F}, {2.1F, 0.9F, 0.0F}, {2.9F, 0.1F, 1.9F},
                    {2.5F, 0.5F, 1.5F}, {2.2F, 0.3F, 0.2F}, {-0.5F, 3.5F, 1.0F}};
  h.build(pts, Pose::Identity(), r);
  ASSERT_EQ(r.cells.size(), 2U);
  EXPECT_EQ(r.points_kept, 6U);
  const ScanCell* c20 = nullptr;
  const ScanCell* cm13 = nullptr;
  for (const auto& c : r.cells) {
    if (c.key == CellKey{2, 0}) c20 = &c;
    if (c.key == CellKey{-1, 3}) cm13 = &c;
  }
  ASSERT_NE(c20, nullptr);
  ASSERT_NE(cm13, nullptr);
  const auto v = r.hvoxels_of(*c20);
  ASSERT_EQ(v.size(), 2U);
  EXPECT_FLOAT_EQ(v[0].z_min, 0.0F);
  EXPECT_FLOAT_EQ(v[0].z_max, 0.4F);
  EXPECT_FLOAT_EQ(v[0].count, 3.0F);
  EXPECT_FLOAT_EQ(v[1].z_min, 1.5F);
  EXPECT_FLOAT_EQ(v[1].z_max, 1.9F);
  EXPECT_FLOAT_EQ(v[1].count, 2.0F);
  // eq. (1): V = 0.4 * 1 m^2, x = 0.0005 * (3 - 5) / 0.4.
  EXPECT_NEAR(v[0].density, 1.0 / (1.0 + std::exp(0.0005 * 2 / 0.4)), 1e-6);
  const auto w = r.hvoxels_of(*cm13);
  ASSERT_EQ(w.size(), 1U);
  EXPECT_FLOAT_EQ(w[0].z_min, 1.0F);
  EXPECT_FLOAT_EQ(w[0].z_max, 1.0F);
}

// The centroids of IndexingAndClusteringByHand's HVoxels, by hand: [0, 0.4] holds (2.5, 0.5),
// (2.1, 0.9), (2.2, 0.3) -> (6.8 / 3, 1.7 / 3); [1.5, 1.9] holds (2.9, 0.1), (2.5, 0.5) -> (2.7, 0.3).
TEST(ScanHVoxelsTest, CentroidsByHand) {
  ScanHVoxelizer h(unit_params());
  ScanHVoxels r;
  const PointCloud pts = {{2.5F, 0.5F, 0.4F}, {2.1F, 0.9F, 0.0F}, {2.9F, 0.1F, 1.9F},
                          {2.5F, 0.5F, 1.5F}, {2.2F, 0.3F, 0.2F}, {-0.5F, 3.5F, 1.0F}};
  h.build(pts, Pose::Identity(), r);
  EXPECT_TRUE(r.centroids.empty()) << "off by default: the mapper does not pay for them";
  h.keep_centroids(true);
  h.build(pts, Pose::Identity(), r);
  ASSERT_EQ(r.centroids.size(), r.hvoxels.size());
  for (const ScanCell& c : r.cells) {
    if (c.key == CellKey{2, 0}) {
      ASSERT_EQ(c.count, 2U);
      EXPECT_NEAR(r.centroids[c.first].x(), 6.8 / 3.0, 1e-6);
      EXPECT_NEAR(r.centroids[c.first].y(), 1.7 / 3.0, 1e-6);
      EXPECT_NEAR(r.centroids[c.first + 1].x(), 2.7, 1e-6);
      EXPECT_NEAR(r.centroids[c.first + 1].y(), 0.3, 1e-6);
    } else {
      EXPECT_NEAR(r.centroids[c.first].x(), -0.5, 1e-6);
      EXPECT_NEAR(r.centroids[c.first].y(), 3.5, 1e-6);
    }
  }
  h.keep_centroids(false);
  h.build(pts, Pose::Identity(), r);
  EXPECT_TRUE(r.centroids.empty()) << "a later build without them leaves none stale";
}

// Under a pose, with dropped points, many cells and clusters: each HVoxel's centroid is the mean
// of the transformed points whose cell and height are its own (a brute-force twin), and lies in
// its cell.
TEST(ScanHVoxelsTest, CentroidsAgreeWithABruteForceTwin) {
  MapParams p = unit_params();
  p.cell_size = 0.2;
  p.point_distance_threshold = 0.3;
  p.min_range = 0.5;
  p.max_range = 8.0;
  ScanHVoxelizer h(p);
  h.keep_centroids(true);
  ScanHVoxels r;
  std::mt19937 rng(2812);
  std::uniform_real_distribution<float> xy(-9.0F, 9.0F);
  std::uniform_real_distribution<float> z(-1.0F, 2.0F);
  PointCloud pts;
  for (int k = 0; k < 20000; ++k) pts.emplace_back(xy(rng), xy(rng), k % 4 == 0 ? 0.0F : z(rng));
  pts.emplace_back(std::numeric_limits<float>::quiet_NaN(), 0.0F, 0.0F);
  Pose T = Pose::Identity();
  T.linear() = (Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(1234.56, -78.9, 0.4);
  h.build(pts, T, r);
  ASSERT_EQ(r.centroids.size(), r.hvoxels.size());
  ASSERT_GT(r.hvoxels.size(), 1000U);
  std::vector<Eigen::Vector3d> sums(r.hvoxels.size(), Eigen::Vector3d::Zero());
  std::size_t assigned = 0;
  for (const Point3f& ps : pts) {
    if (!ps.allFinite()) continue;
    const double range = ps.cast<double>().norm();
    if (range < p.min_range || range > p.max_range) continue;
    const Eigen::Vector3d q = T * ps.cast<double>();
    const CellKey key{static_cast<std::int32_t>(std::floor(q.x() / p.cell_size)),
                      static_cast<std::int32_t>(std::floor(q.y() / p.cell_size))};
    for (const ScanCell& c : r.cells) {
      if (!(c.key == key)) continue;
      for (std::uint32_t k = c.first; k < c.first + c.count; ++k) {
        if (std::abs(q.z() - r.hvoxels[k].z_min) < 1e-4 || std::abs(q.z() - r.hvoxels[k].z_max) < 1e-4 ||
            (q.z() > r.hvoxels[k].z_min && q.z() < r.hvoxels[k].z_max)) {
          sums[k] += Eigen::Vector3d(q.x(), q.y(), 1.0);
          ++assigned;
          break;
        }
      }
    }
  }
  EXPECT_EQ(assigned, r.points_kept);
  for (const ScanCell& c : r.cells) {
    for (std::uint32_t k = c.first; k < c.first + c.count; ++k) {
      ASSERT_EQ(sums[k].z(), static_cast<double>(r.hvoxels[k].count));
      const Eigen::Vector2d mean = sums[k].head<2>() / sums[k].z();
      EXPECT_NEAR(r.centroids[k].x(), mean.x(), 2e-4);
      EXPECT_NEAR(r.centroids[k].y(), mean.y(), 2e-4);
      EXPECT_GE(r.centroids[k].x(), c.key.i * p.cell_size - 2e-4);
      EXPECT_LE(r.centroids[k].x(), (c.key.i + 1) * p.cell_size + 2e-4);
      EXPECT_GE(r.centroids[k].y(), c.key.j * p.cell_size - 2e-4);
      EXPECT_LE(r.centroids[k].y(), (c.key.j + 1) * p.cell_size + 2e-4);
    }
  }
}

// build() with work alongside the centroids' sums: the same HVoxels, centroids and wall lean as
// without, and the work sees the HVoxels as they end (a copy taken inside it matches); without
// centroids kept the work still runs, once.
TEST(ScanHVoxelsTest, WorkAlongsideSeesTheFinalHVoxelsAndChangesNothing) {
  MapParams p = unit_params();
  p.cell_size = 0.25;
  p.point_distance_threshold = 0.3;
  std::mt19937 rng(4711);
  std::uniform_real_distribution<float> xy(-7.0F, 7.0F);
  std::uniform_real_distribution<float> z(-1.0F, 2.0F);
  PointCloud pts;
  for (int k = 0; k < 30000; ++k) pts.emplace_back(xy(rng), xy(rng), k % 3 == 0 ? -1.0F : z(rng));
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()).toRotationMatrix();
  for (const bool centroids : {true, false}) {
    ScanHVoxelizer plain(p);
    ScanHVoxelizer with_work(p);
    plain.keep_centroids(centroids);
    plain.keep_wall_lean(centroids);
    with_work.keep_centroids(centroids);
    with_work.keep_wall_lean(centroids);
    ScanHVoxels a;
    ScanHVoxels b;
    plain.build(pts, T, a);
    std::vector<HVoxel> seen;
    int calls = 0;
    with_work.build(pts, T, b, [&](const ScanHVoxels& r) {
      seen = r.hvoxels;
      ++calls;
    });
    EXPECT_EQ(calls, 1);
    ASSERT_EQ(a.hvoxels.size(), b.hvoxels.size());
    ASSERT_GT(a.hvoxels.size(), 500U);
    ASSERT_EQ(seen.size(), b.hvoxels.size());
    for (std::size_t k = 0; k < a.hvoxels.size(); ++k) {
      EXPECT_EQ(a.hvoxels[k].z_min, b.hvoxels[k].z_min);
      EXPECT_EQ(a.hvoxels[k].z_max, b.hvoxels[k].z_max);
      EXPECT_EQ(a.hvoxels[k].count, b.hvoxels[k].count);
      EXPECT_EQ(seen[k].z_min, b.hvoxels[k].z_min);
      EXPECT_EQ(seen[k].count, b.hvoxels[k].count);
    }
    ASSERT_EQ(a.centroids.size(), centroids ? a.hvoxels.size() : 0U);
    ASSERT_EQ(b.centroids.size(), a.centroids.size());
    for (std::size_t k = 0; k < a.centroids.size(); ++k) EXPECT_EQ(a.centroids[k], b.centroids[k]);
    EXPECT_EQ(a.wall_lean.walls, b.wall_lean.walls);
    EXPECT_EQ(a.wall_lean.weighted, b.wall_lean.weighted);
  }
}

/// Vertical walls sampled as a spinning lidar's rings would (heights −1 to 2 m every 0.2 m,
/// 2 cm apart along the wall, 1 cm of noise across it, fixed seed), seen from a sensor tilted by
/// `tilt` (sensor → level): what the binning frame holds when its z is not gravity's.
PointCloud tilted_walls(const Eigen::Matrix3d& tilt, bool three_walls) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.01);
  PointCloud out;
  const auto wall = [&](const Eigen::Vector2d& from, const Eigen::Vector2d& to) {
    const Eigen::Vector2d along = (to - from).normalized();
    const Eigen::Vector2d normal(-along.y(), along.x());
    for (double s = 0.0; s <= (to - from).norm(); s += 0.02) {
      for (double z = -1.0; z <= 2.0 + 1e-9; z += 0.2) {
        const Eigen::Vector2d xy = from + s * along + noise(rng) * normal;
        out.push_back((tilt.transpose() * Eigen::Vector3d(xy.x(), xy.y(), z)).cast<float>());
      }
    }
  };
  // Mid-cell (0.25 m cells): a wall on a cell's edge is cut by it, each side keeps a truncated
  // share of its lean (half of it at the edge).
  wall({-4.1, 5.1}, {6.1, 5.1});
  if (three_walls) {
    wall({-4.1, -5.1}, {-4.1, 4.1});
    wall({6.1, -5.1}, {6.1, 4.1});
  }
  return out;
}

/// A builder of 0.25 m cells, with the height gap and range given, that measures the walls' lean.
ScanHVoxelizer wall_lean_builder(double gap, double max_range) {
  MapParams p = unit_params();
  p.cell_size = 0.25;
  p.point_distance_threshold = gap;
  p.max_range = max_range;
  ScanHVoxelizer b(p);
  b.keep_centroids(true);
  b.keep_wall_lean(true);
  return b;
}

// A level frame tilted by 0.57° about x and −0.34° about y: verticals lean by tiltᵀ·ẑ in it, and
// the walls read it within 0.03°; one wall holds only its normal's axis.
TEST(ScanHVoxelsTest, WallLeanReadsTheFramesTilt) {
  ScanHVoxelizer b = wall_lean_builder(0.4, 10.0);
  const Eigen::Matrix3d tilt =
      (Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(-0.006, Eigen::Vector3d::UnitY())).toRotationMatrix();
  // Binned at the identity, the walls stand along tiltᵀ·ẑ.
  const Eigen::Vector3d up = tilt.transpose() * Eigen::Vector3d::UnitZ();
  ScanHVoxels r;
  b.build(tilted_walls(tilt, true), Pose::Identity(), r);
  ASSERT_GT(r.wall_lean.walls, 100U);
  const Eigen::Vector2d lean = r.wall_lean.lean();
  EXPECT_NEAR(lean.x(), up.x() / up.z(), 5e-4);
  EXPECT_NEAR(lean.y(), up.y() / up.z(), 5e-4);
  EXPECT_GT(r.wall_lean.weakest(), 0.0);
  // Untilted: no lean.
  b.build(tilted_walls(Eigen::Matrix3d::Identity(), true), Pose::Identity(), r);
  EXPECT_NEAR(r.wall_lean.lean().norm(), 0.0, 5e-4);
  // One wall along x: its normal (y) is held, x is not.
  b.build(tilted_walls(tilt, false), Pose::Identity(), r);
  ASSERT_GT(r.wall_lean.walls, 20U);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(r.wall_lean.information);
  EXPECT_LT(eig.eigenvalues()(0), 1e-3 * eig.eigenvalues()(1));
  EXPECT_NEAR(std::abs(eig.eigenvectors().col(1).y()), 1.0, 1e-3);
  EXPECT_NEAR(r.wall_lean.weighted.y() / r.wall_lean.information(1, 1), up.y() / up.z(), 5e-4);
  EXPECT_NEAR(r.wall_lean.lean().y(), up.y() / up.z(), 5e-4);  // the held axis
  EXPECT_NEAR(r.wall_lean.lean().x(), 0.0, 1e-4);  // and the other, held under 1e-3 as much, left at zero
  // Nothing tall (a floor), and a builder not asked: no walls.
  PointCloud floor;
  for (double x = -5.0; x < 5.0; x += 0.05) {
    for (double y = -5.0; y < 5.0; y += 0.05) floor.push_back(Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), -1.5F));
  }
  b.build(floor, Pose::Identity(), r);
  EXPECT_EQ(r.wall_lean.walls, 0U);
  EXPECT_EQ(r.wall_lean.lean(), Eigen::Vector2d::Zero());
  ScanHVoxelizer plain = wall_lean_builder(0.4, 10.0);
  plain.keep_wall_lean(false);
  plain.build(tilted_walls(tilt, true), Pose::Identity(), r);
  EXPECT_EQ(r.wall_lean.walls, 0U);
}

/// A street seen by a LiDAR that fires all its beams at one azimuth at a time (64 beams from
/// −45° to 45°, 1024 columns, 1.5 cm of range noise, fixed seed), its axis tilted by `tilt`
/// (sensor → gravity): walls 15 m tall 8 m to either side along x and 15 m ahead and behind,
/// the ground 1.8 m below, none on a 0.25 m cell's edge.
PointCloud column_lidar_street(const Eigen::Matrix3d& tilt) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.015);
  PointCloud out;
  constexpr double kPi = 3.14159265358979323846;
  for (int c = 0; c < 1024; ++c) {
    const double azimuth = 2.0 * kPi * (c + 0.5) / 1024.0;
    for (int b = 0; b < 64; ++b) {
      const double elevation = (-45.0 + 90.0 * b / 63.0) * kPi / 180.0;
      const Eigen::Vector3d d_sensor(std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                                     std::sin(elevation));
      const Eigen::Vector3d d = tilt * d_sensor;
      double t = std::numeric_limits<double>::infinity();
      const auto hit = [&](double along, double at, double low, double high, int axis) {
        // the plane `axis` = at, where the other horizontal coordinate lies in [low, high] and z in [−1.8, 15]
        if (std::abs(along) < 1e-9) return;
        const double s = at / along;
        if (!(s > 0.0) || s >= t) return;
        const Eigen::Vector3d p = s * d;
        const double other = axis == 0 ? p.y() : p.x();
        if (other < low || other > high || p.z() < -1.8 || p.z() > 15.0) return;
        t = s;
      };
      hit(d.y(), 8.07, -14.91, 15.13, 1);
      hit(d.y(), -8.07, -14.91, 15.13, 1);
      hit(d.x(), 15.13, -8.07, 8.07, 0);
      hit(d.x(), -14.91, -8.07, 8.07, 0);
      if (d.z() < 0.0) {
        const double s = -1.8 / d.z();
        if (s < t) t = s;
      }
      if (!std::isfinite(t) || t > 40.0) continue;
      out.push_back(((t + noise(rng)) * d_sensor).cast<float>());
    }
  }
  return out;
}

// What made the walls read a town's 1.1° tilt as a third of it (OS0-64, session 32), taken out:
// a LiDAR's column of beams at one azimuth lies along the ray in plan, changing with height only
// as its wall leans, so it looked like a wall across the ray that leaned not at all; and walls
// whose scatter a cell's edge had cut weighed most. Binned in the sensor's frame, 1.15° off
// gravity about y and 0.57° about x, the street's walls must read the tilt within 20 %.
TEST(ScanHVoxelsTest, WallLeanIsNotFooledByBeamColumns) {
  ScanHVoxelizer b = wall_lean_builder(0.62, 40.0);
  const Eigen::Matrix3d tilt =
      (Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX())).toRotationMatrix();
  const Eigen::Vector3d up = tilt.transpose() * Eigen::Vector3d::UnitZ();  // the vertical in the sensor's frame
  ScanHVoxels r;
  b.build(column_lidar_street(tilt), Pose::Identity(), r);
  ASSERT_GT(r.wall_lean.walls, 50U);
  const Eigen::Vector2d lean = r.wall_lean.lean();
  EXPECT_NEAR(lean.x(), up.x() / up.z(), 0.2 * std::abs(up.x() / up.z())) << "lean " << lean.transpose();
  EXPECT_NEAR(lean.y(), up.y() / up.z(), 0.2 * std::abs(up.y() / up.z())) << "lean " << lean.transpose();
  // Level, the same street reads no lean.
  b.build(column_lidar_street(Eigen::Matrix3d::Identity()), Pose::Identity(), r);
  EXPECT_LT(r.wall_lean.lean().norm(), 1e-3) << r.wall_lean.lean().transpose();
}

TEST(ScanHVoxelsTest, ThresholdBoundary) {
  MapParams p = unit_params();
  p.point_distance_threshold = 0.25;  // exactly representable, as are the heights below
  ScanHVoxelizer h(p);
  ScanHVoxels r;
  // Gap of exactly the threshold joins; a gap just above splits.
  PointCloud pts = {{0.5F, 0.5F, 0.0F}, {0.5F, 0.5F, 0.25F}, {0.5F, 0.5F, 0.5F + 0.001F}};
  h.build(pts, Pose::Identity(), r);
  ASSERT_EQ(r.cells.size(), 1U);
  const auto v = r.hvoxels_of(r.cells[0]);
  ASSERT_EQ(v.size(), 2U);
  EXPECT_FLOAT_EQ(v[0].z_max, 0.25F);
  EXPECT_FLOAT_EQ(v[1].z_min, 0.501F);
}

// map.ring_gap_slope by hand: the gap of a cell is max(threshold, min(slope · d, most)), d its
// centre's distance from the sensor plus half its diagonal. Heights 0, 0.7, 1.4 (gaps 0.7):
// - cell (20, 0): d = hypot(20.5, 0.5) + 0.7071 = 21.2132; slope 0.04 -> gap 0.8485: one HVoxel;
// - cell (4, 0): d = hypot(4.5, 0.5) + 0.7071 = 5.2348 -> 0.2094, the threshold 0.5: three;
// - the sensor moved to x = 16: cell (20, 0) is then as near, three; slope 0 anywhere: three;
// - slope 0.1 at cell (20, 0): 2.1213 m, within the default most (map.ring_gap_max, 3 m): heights
//   0 and 2.1 are one HVoxel, 0 and 2.15 two; held to a most of 1 m, 0 and 1.05 split.
TEST(ScanHVoxelsTest, RingGapGrowsWithTheCellsDistance) {
  MapParams p = unit_params();
  p.max_range = 30.0;
  p.ring_gap_slope = 0.04;
  const auto column = [](float x, std::initializer_list<float> heights) {
    PointCloud pts;
    for (const float z : heights) pts.emplace_back(x, 0.5F, z);
    return pts;
  };
  const auto count = [](const MapParams& mp, const PointCloud& pts, double sensor_x) {
    ScanHVoxelizer h(mp);
    ScanHVoxels r;
    Pose T = Pose::Identity();
    T.translation().x() = sensor_x;
    PointCloud in_sensor = pts;
    for (Point3f& q : in_sensor) q.x() -= static_cast<float>(sensor_x);
    h.build(in_sensor, T, r);
    EXPECT_EQ(r.cells.size(), 1U);
    return r.hvoxels.size();
  };
  EXPECT_EQ(count(p, column(20.5F, {0.0F, 0.7F, 1.4F}), 0.0), 1U);
  EXPECT_EQ(count(p, column(4.5F, {0.0F, 0.7F, 1.4F}), 0.0), 3U);
  EXPECT_EQ(count(p, column(20.5F, {0.0F, 0.7F, 1.4F}), 16.0), 3U);
  // The gap just under and over 0.8485 m at cell (20, 0).
  EXPECT_EQ(count(p, column(20.5F, {0.0F, 0.84F}), 0.0), 1U);
  EXPECT_EQ(count(p, column(20.5F, {0.0F, 0.86F}), 0.0), 2U);
  MapParams fixed = p;
  fixed.ring_gap_slope = 0.0;
  EXPECT_EQ(count(fixed, column(20.5F, {0.0F, 0.7F, 1.4F}), 0.0), 3U);
  MapParams steep = p;
  steep.ring_gap_slope = 0.1;
  EXPECT_DOUBLE_EQ(steep.ring_gap_max, 3.0);
  EXPECT_EQ(count(steep, column(20.5F, {0.0F, 2.1F}), 0.0), 1U);
  EXPECT_EQ(count(steep, column(20.5F, {0.0F, 2.15F}), 0.0), 2U);
  steep.ring_gap_max = 1.0;
  EXPECT_EQ(count(steep, column(20.5F, {0.0F, 0.99F}), 0.0), 1U);
  EXPECT_EQ(count(steep, column(20.5F, {0.0F, 1.05F}), 0.0), 2U);
  // A threshold above the most stays the gap.
  steep.point_distance_threshold = 1.5;
  EXPECT_EQ(count(steep, column(20.5F, {0.0F, 1.45F}), 0.0), 1U);
  // The same HVoxels whatever the order of the heights (the one-cluster shortcut and the sort).
  EXPECT_EQ(count(p, column(20.5F, {1.4F, 0.0F, 0.7F, 3.0F, 2.3F}), 0.0), 2U);
}

TEST(ScanHVoxelsTest, DropsNonFiniteAndOutOfRangeAndCounts) {
  MapParams p = unit_params();
  p.min_range = 1.0;
  p.max_range = 5.0;
  ScanHVoxelizer h(p);
  ScanHVoxels r;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  PointCloud pts = {{nan, 0, 0}, {0, inf, 0}, {0.5F, 0, 0}, {6.0F, 0, 0}, {1e30F, 0, 0},
                    {2.0F, 0, 0}, {0, -3.0F, 1.0F}};
  h.build(pts, Pose::Identity(), r);
  EXPECT_EQ(r.points_in, 7U);
  EXPECT_EQ(r.dropped_non_finite, 2U);
  EXPECT_EQ(r.dropped_range, 3U);
  EXPECT_EQ(r.points_kept, 2U);
  EXPECT_EQ(r.cells.size(), 2U);
}

TEST(ScanHVoxelsTest, TransformsToMapFrameBeforeBinning) {
  ScanHVoxelizer h(unit_params());
  ScanHVoxels r;
  Pose T = Pose::Identity();
  T.translate(Eigen::Vector3d(100.0, -50.0, 2.0));
  T.rotate(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  PointCloud pts = {{3.5F, 0.0F, 0.0F}};  // rotated to (0, 3.5), translated to (100, -46.5, 2)
  h.build(pts, T, r);
  ASSERT_EQ(r.cells.size(), 1U);
  EXPECT_EQ(r.cells[0].key, (CellKey{100, -47}));
  EXPECT_FLOAT_EQ(r.hvoxels[0].z_min, 2.0F);
  EXPECT_EQ(r.origin_map, Eigen::Vector3d(100.0, -50.0, 2.0));
}

TEST(ScanHVoxelsTest, BuffersAreReusedAcrossScans) {
  ScanHVoxelizer h(unit_params());
  ScanHVoxels r;
  PointCloud a = {{1.5F, 1.5F, 0.0F}};
  PointCloud b = {{-2.5F, 1.5F, 0.0F}};
  h.build(a, Pose::Identity(), r);
  h.build(b, Pose::Identity(), r);
  ASSERT_EQ(r.cells.size(), 1U);
  EXPECT_EQ(r.cells[0].key, (CellKey{-3, 1}));
  EXPECT_EQ(r.hvoxels.size(), 1U);
}

TEST(ScanHVoxelsTest, NonFinitePoseIsAnError) {
  ScanHVoxelizer h(unit_params());
  ScanHVoxels r;
  Pose T = Pose::Identity();
  T.translation().x() = std::numeric_limits<double>::quiet_NaN();
  PointCloud a = {{1.5F, 1.5F, 0.0F}};
  EXPECT_THROW(h.build(a, T, r), Error);
}

// Alg. 2 against a brute-force twin (each cell's heights sorted in full, split where a gap exceeds
// the threshold), over cells of 1 to 150 points in every order the sorting paths meet: ascending,
// descending (a spinning sensor's rings from the top down), shuffled, and with ties. Two in five
// cells span the threshold or less, some exactly, and are one HVoxel whatever their order; some
// span just more, and split.
TEST(ScanHVoxelsTest, ClustersAgreeWithASortedTwinInEveryOrder) {
  MapParams p = unit_params();
  p.point_distance_threshold = 0.25;
  p.max_range = 100.0;
  ScanHVoxelizer h(p);
  ScanHVoxels r;
  std::mt19937 rng(2212);
  std::uniform_real_distribution<float> unit(0.0F, 1.0F);
  for (int trial = 0; trial < 50; ++trial) {
    PointCloud pts;
    std::vector<std::vector<float>> heights_of_cell;
    for (int c = 0; c < 60; ++c) {
      const int n = 1 + static_cast<int>(rng() % (c % 3 == 0 ? 150U : 20U));
      std::vector<float> z(static_cast<std::size_t>(n));
      const int kind = static_cast<int>(rng() % 5);
      for (float& v : z) {
        switch (kind) {
          case 0: v = 0.25F * unit(rng); break;                            // within the threshold
          case 1: v = static_cast<float>(rng() % 2) * 0.25F; break;        // span exactly 0.25, ties
          case 2: v = 3.0F * unit(rng); break;                             // several clusters
          case 3: v = static_cast<float>(rng() % 2) * 0.3F; break;         // a gap just above it
          default: v = (rng() % 3 == 0 ? 1.5F : 0.0F) + 0.2F * unit(rng);  // two clusters
        }
      }
      const int order = static_cast<int>(rng() % 3);
      if (order == 0) std::sort(z.begin(), z.end());
      if (order == 1) std::sort(z.begin(), z.end(), std::greater<>());
      const float x = 0.5F + static_cast<float>(c % 8);
      const float y = 0.5F + static_cast<float>(c / 8);
      for (const float v : z) pts.emplace_back(x, y, v);
      heights_of_cell.push_back(z);
    }
    h.build(pts, Pose::Identity(), r);
    ASSERT_EQ(r.cells.size(), heights_of_cell.size());
    for (std::size_t c = 0; c < heights_of_cell.size(); ++c) {
      std::vector<float> z = heights_of_cell[c];
      std::sort(z.begin(), z.end());
      std::vector<HVoxel> twin;
      std::size_t first = 0;
      for (std::size_t k = 1; k <= z.size(); ++k) {
        if (k == z.size() || z[k] - z[k - 1] > 0.25F) {
          twin.push_back({z[first], z[k - 1], static_cast<float>(k - first), 0.0F});
          first = k;
        }
      }
      const ScanCell& cell = r.cells[c];  // cells are numbered in order of first appearance
      ASSERT_EQ(cell.key, (CellKey{static_cast<std::int32_t>(c % 8), static_cast<std::int32_t>(c / 8)}));
      const auto v = r.hvoxels_of(cell);
      ASSERT_EQ(v.size(), twin.size()) << "trial " << trial << " cell " << c;
      for (std::size_t k = 0; k < twin.size(); ++k) {
        EXPECT_EQ(v[k].z_min, twin[k].z_min);
        EXPECT_EQ(v[k].z_max, twin[k].z_max);
        EXPECT_EQ(v[k].count, twin[k].count);
        EXPECT_FLOAT_EQ(v[k].density, hvoxel_density(twin[k].count, twin[k].height(), p));
      }
    }
  }
}

}  // namespace
}  // namespace hmap
