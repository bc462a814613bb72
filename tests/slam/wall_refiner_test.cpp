#include "hmap/slam/wall_refiner.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/maps/scan_hvoxels.hpp"

namespace hmap::slam {
namespace wall_refiner_test {

constexpr double kDeg = std::numbers::pi / 180.0;

Params params_at(double cell) {
  Params p;
  p.map.cell_size = cell;
  return p;
}

/// Points along the segment a -> b every `step` metres, each moved across it by N(0, noise).
void segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double step, double noise, std::mt19937& rng,
             std::vector<Eigen::Vector3d>& out, double z = 1.2) {
  std::normal_distribution<double> n(0.0, noise);
  const Eigen::Vector2d d = b - a;
  const double length = d.norm();
  const Eigen::Vector2d across{-d.y() / length, d.x() / length};
  for (double t = 0.0; t <= length; t += step) {
    const Eigen::Vector2d p = a + d * (t / length) + across * n(rng);
    out.emplace_back(p.x(), p.y(), z);
  }
}

/// A room with a few walls inside it, at several headings (world frame).
std::vector<Eigen::Vector3d> room(double step, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<Eigen::Vector3d> w;
  const double noise = 0.01;
  segment({-6, -4}, {7, -4}, step, noise, rng, w);
  segment({7, -4}, {7, 5}, step, noise, rng, w);
  segment({7, 5}, {-6, 5}, step, noise, rng, w);
  segment({-6, 5}, {-6, -4}, step, noise, rng, w);
  segment({-3, -1}, {1, 2.5}, step, noise, rng, w);   // about 41 deg
  segment({3, 1}, {5.5, -2.2}, step, noise, rng, w);  // about -52 deg
  return w;
}

/// World points seen from a sensor at `pose`: p_sensor = R(-yaw) (p - t).
std::vector<Eigen::Vector3d> seen_from(const std::vector<Eigen::Vector3d>& world, const PlanarPose& pose) {
  const double c = std::cos(pose.yaw);
  const double s = std::sin(pose.yaw);
  std::vector<Eigen::Vector3d> out;
  for (const Eigen::Vector3d& p : world) {
    const Eigen::Vector2d d = p.head<2>() - Eigen::Vector2d(pose.x, pose.y);
    out.emplace_back(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), p.z());
  }
  return out;
}

TEST(WallGrid, AccumulatesMomentsPerCellAndBandAboutItsCorner) {
  WallGrid grid(0.5, 1.0);
  const std::vector<Eigen::Vector3d> pts{{0.1, 0.2, 0.5}, {0.3, 0.4, 0.9}, {-0.1, 0.2, 0.0}, {0.1, 0.2, 1.5}};
  grid.add(pts);
  ASSERT_EQ(grid.size(), 3U);
  const PlanMoments* m = grid.at({0, 0, 0});
  ASSERT_NE(m, nullptr);
  EXPECT_FLOAT_EQ(m->n, 2.0F);
  EXPECT_FLOAT_EQ(m->sx, 0.4F);
  EXPECT_FLOAT_EQ(m->sy, 0.6F);
  EXPECT_FLOAT_EQ(m->sxx, 0.1F);
  EXPECT_FLOAT_EQ(m->sxy, 0.14F);
  const PlanMoments* other = grid.at({-1, 0, 0});  // x = -0.1 lies in the cell [-0.5, 0)
  ASSERT_NE(other, nullptr);
  EXPECT_FLOAT_EQ(other->sx, 0.4F);               // -0.1 - (-0.5)
  const PlanMoments* above = grid.at({0, 0, 1});   // z = 1.5: the band [1, 2)
  ASSERT_NE(above, nullptr);
  EXPECT_FLOAT_EQ(above->n, 1.0F);
  EXPECT_EQ(grid.at({5, 5, 0}), nullptr);
  // Through a pose: (1, 0) turned 90 deg and moved by (0.2, 0.1) is (0.2, 1.1); z is kept.
  WallGrid moved(0.5, 1.0);
  const std::vector<Eigen::Vector3d> one{{1.0, 0.0, -0.5}};
  moved.add(one, PlanarPose{0.2, 0.1, std::numbers::pi / 2.0});
  ASSERT_NE(moved.at({0, 2, -1}), nullptr);
  EXPECT_NEAR(moved.at({0, 2, -1})->sx, 0.2F, 1e-6);
  EXPECT_NEAR(moved.at({0, 2, -1})->sy, 0.1F, 1e-6);
  // Non-finite points are skipped.
  const std::vector<Eigen::Vector3d> bad{{std::nan(""), 0.0, 0.0}, {std::numeric_limits<double>::infinity(), 1.0, 0.0},
                                         {0.0, 0.0, std::nan("")}};
  moved.add(bad);
  EXPECT_EQ(moved.size(), 1U);
  EXPECT_THROW(WallGrid(0.0, 1.0), Error);
  EXPECT_THROW(WallGrid(-1.0, 1.0), Error);
  EXPECT_THROW(WallGrid(0.5, 0.0), Error);
  EXPECT_THROW(WallGrid(0.5, std::nan("")), Error);
}

TEST(WallGrid, LineAroundACellFitsTheLineThroughItsNeighbours) {
  // y = 0.3 x + 0.1, 0.01 m apart, over a few cells: normal (-0.3, 1)/|.|, no thickness.
  WallGrid grid(0.25, 0.5);
  std::vector<Eigen::Vector3d> pts;
  for (double x = -1.0; x <= 1.0; x += 0.01) pts.emplace_back(x, 0.3 * x + 0.1, 0.2);
  grid.add(pts);
  const auto line = line_around(grid, grid.key_of(0.0, 0.1, 0.2), 8.0, 0.05);
  ASSERT_TRUE(line.has_value());
  const Eigen::Vector2d expected = Eigen::Vector2d(-0.3, 1.0).normalized();
  EXPECT_NEAR(std::abs(line->normal.dot(expected)), 1.0, 1e-6);
  EXPECT_NEAR(line->centre.y(), 0.3 * line->centre.x() + 0.1, 1e-5);  // the centroid is on the line
  EXPECT_NEAR(line->thickness, 0.0, 1e-3);
  // An isotropic blob is no line; nor are too few points; nor an empty neighbourhood.
  // Another band sees nothing of it.
  EXPECT_FALSE(line_around(grid, grid.key_of(0.0, 0.1, 1.2), 8.0, 0.05).has_value());
  WallGrid blob(0.25, 0.5);
  std::vector<Eigen::Vector3d> b;
  for (double x = -0.3; x <= 0.3; x += 0.02) {
    for (double y = -0.3; y <= 0.3; y += 0.02) b.emplace_back(x, y, 0.2);
  }
  blob.add(b);
  EXPECT_FALSE(line_around(blob, {0, 0, 0}, 8.0, 1.0).has_value());
  EXPECT_FALSE(line_around(grid, grid.key_of(0.0, 0.1, 0.2), 1e6, 0.05).has_value());
  EXPECT_FALSE(line_around(grid, {100, 100, 0}, 8.0, 0.05).has_value());
  // A thick line is refused by the thickness bound, kept under a looser one.
  WallGrid thick(0.25, 0.5);
  std::vector<Eigen::Vector3d> t;
  std::mt19937 rng(3);
  segment({-1, 0}, {1, 0}, 0.005, 0.04, rng, t, 0.2);
  thick.add(t);
  EXPECT_FALSE(line_around(thick, {0, 0, 0}, 8.0, 0.02).has_value());
  EXPECT_TRUE(line_around(thick, {0, 0, 0}, 8.0, 0.1).has_value());
}

TEST(WallRefiner, RecoversASubCellMoveAndTurnOfTheSensor) {
  // The map holds the room seen from the origin; the scan sees it (other samples) from a pose a
  // few centimetres and 0.3 deg away, which binned at 0.25 m cells would mostly share the map's cells.
  const Params p = params_at(0.25);
  WallRefiner refiner(p);
  WallGrid map(0.25, 0.5);
  const auto world_map = room(0.01, 1);
  map.add(world_map);
  const PlanarPose truth{0.04, -0.03, 0.3 * kDeg};
  WallGrid scan(0.25, 0.5);
  scan.add(seen_from(room(0.013, 2), truth));
  const WallRefinement r = refiner.refine(scan, map, PlanarPose{});
  ASSERT_TRUE(r.applied) << r.skipped_because;
  EXPECT_NEAR(r.pose.x, truth.x, 0.004);
  EXPECT_NEAR(r.pose.y, truth.y, 0.004);
  EXPECT_NEAR(r.pose.yaw, truth.yaw, 0.03 * kDeg);
  EXPECT_GE(r.pairs, 100U);
  EXPECT_LT(r.rms, 0.02);
  EXPECT_GT(r.eigenvalues(0), 0.0);
}

TEST(WallRefiner, AlongACorridorKeepsTheGuessAlongIt) {
  // Two parallel walls along x: y and yaw are told, x is not and keeps the guess.
  const Params p = params_at(0.25);
  WallRefiner refiner(p);
  std::mt19937 rng(5);
  std::vector<Eigen::Vector3d> world;
  segment({-10, -1.5}, {10, -1.5}, 0.01, 0.005, rng, world);
  segment({-10, 1.5}, {10, 1.5}, 0.01, 0.005, rng, world);
  WallGrid map(0.25, 0.5);
  map.add(world);
  const PlanarPose truth{0.0, 0.05, 0.0};
  WallGrid scan(0.25, 0.5);
  std::vector<Eigen::Vector3d> seen;
  segment({-8, -1.5}, {8, -1.5}, 0.013, 0.005, rng, seen);
  segment({-8, 1.5}, {8, 1.5}, 0.013, 0.005, rng, seen);
  scan.add(seen_from(seen, truth));
  const PlanarPose guess{0.07, 0.0, 0.0};
  const WallRefinement r = refiner.refine(scan, map, guess);
  ASSERT_TRUE(r.applied) << r.skipped_because;
  EXPECT_NEAR(r.pose.y, truth.y, 0.004);
  EXPECT_NEAR(r.pose.x, guess.x, 1e-6);  // along the corridor: the guess's
  EXPECT_LT(r.eigenvalues(0), 0.02 * r.eigenvalues(2));
}

TEST(WallRefiner, KeepsTheGuessWithTooFewWallsOrTooFarAMove) {
  const Params p = params_at(0.25);
  WallRefiner refiner(p);
  WallGrid map(0.25, 0.5);
  map.add(room(0.01, 1));
  const PlanarPose guess{0.01, 0.02, 0.001};
  // An empty scan, a scan of one short wall.
  WallGrid empty(0.25, 0.5);
  WallRefinement r = refiner.refine(empty, map, guess);
  EXPECT_FALSE(r.applied);
  EXPECT_STRNE(r.skipped_because, "");
  EXPECT_EQ(r.pose.x, guess.x);
  EXPECT_EQ(r.pose.yaw, guess.yaw);
  std::mt19937 rng(7);
  std::vector<Eigen::Vector3d> short_wall;
  segment({-1, -4}, {0, -4}, 0.01, 0.005, rng, short_wall);
  WallGrid few(0.25, 0.5);
  few.add(short_wall);
  r = refiner.refine(few, map, guess);
  EXPECT_FALSE(r.applied);
  EXPECT_EQ(r.pose.y, guess.y);
  // A map with nothing where the scan's walls are.
  WallGrid elsewhere(0.25, 0.5);
  std::vector<Eigen::Vector3d> far;
  segment({100, 100}, {110, 100}, 0.01, 0.005, rng, far);
  elsewhere.add(far);
  WallGrid scan(0.25, 0.5);
  scan.add(room(0.013, 2));
  r = refiner.refine(scan, elsewhere, PlanarPose{});
  EXPECT_FALSE(r.applied);
  // Turned farther than slam.wall_max_rotation allows: kept.
  Params tight = p;
  tight.slam.wall_max_rotation = 0.1 * kDeg;
  WallRefiner strict(tight);
  WallGrid turned(0.25, 0.5);
  turned.add(seen_from(room(0.013, 2), PlanarPose{0.0, 0.0, 0.4 * kDeg}));
  r = strict.refine(turned, map, PlanarPose{});
  EXPECT_FALSE(r.applied);
  EXPECT_EQ(r.pose.yaw, 0.0);
  r = refiner.refine(turned, map, PlanarPose{});
  EXPECT_TRUE(r.applied);
  EXPECT_NEAR(r.pose.yaw, 0.4 * kDeg, 0.03 * kDeg);
}

TEST(WallRefiner, CollectsThePointsOfTallHVoxelsOnly) {
  // A wall 2 m tall at x = 3 and a floor at z = -1 around the sensor: the wall's points are
  // collected, the floor's and the far ones (beyond map.max_range) not.
  Params p = params_at(0.25);
  p.map.max_range = 10.0;
  std::vector<Point3f> points;
  for (double y = -2.0; y <= 2.0; y += 0.05) {
    for (double z = -1.0; z <= 1.0; z += 0.05) points.emplace_back(3.0F, static_cast<float>(y), static_cast<float>(z));
  }
  const std::size_t wall = points.size();
  for (double x = -2.0; x <= 2.5; x += 0.1) {
    for (double y = -2.0; y <= 2.0; y += 0.1) points.emplace_back(static_cast<float>(x), static_cast<float>(y), -1.0F);
  }
  points.emplace_back(20.0F, 0.0F, 0.0F);                      // out of range
  points.emplace_back(std::nanf(""), 0.0F, 0.0F);              // not finite
  ScanHVoxelizer hvoxelizer(p.map);
  ScanHVoxels scan;
  hvoxelizer.build(points, Pose::Identity(), scan);
  WallRefiner refiner(p);
  std::vector<Eigen::Vector3d> out;
  refiner.collect(points, Pose::Identity(), scan, hvoxelizer.cell_of_window(), out);
  ASSERT_EQ(out.size(), wall);
  for (const Eigen::Vector3d& q : out) {
    EXPECT_NEAR(q.x(), 3.0, 1e-6);
    EXPECT_GE(q.z(), -1.0 - 1e-6);
    EXPECT_LE(q.z(), 1.0 + 1e-6);
  }
  // Taller than any HVoxel: nothing.
  p.slam.wall_min_height = 5.0;
  WallRefiner none(p);
  none.collect(points, Pose::Identity(), scan, hvoxelizer.cell_of_window(), out);
  EXPECT_TRUE(out.empty());
}

TEST(WallRefiner, RefusesInvalidParameters) {
  Params p = params_at(0.25);
  p.slam.wall_min_height = -1.0;
  EXPECT_THROW(WallRefiner{p}, Error);
  p = params_at(0.25);
  p.slam.wall_refine = 2;
  EXPECT_THROW(WallRefiner{p}, Error);
  p = params_at(0.25);
  p.slam.wall_max_rotation = std::nan("");
  EXPECT_THROW(WallRefiner{p}, Error);
  p = params_at(0.25);
  p.slam.wall_band_height = 0.0;
  EXPECT_THROW(WallRefiner{p}, Error);
}

}  // namespace wall_refiner_test
}  // namespace hmap::slam
