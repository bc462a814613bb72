#include "hmap/eval/grid_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "hmap/occupancy/hybrid_mapper.hpp"
#include "hmap/sim/composites.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap {
namespace {

constexpr double kCell = 0.25;

CellKey key_at(double x, double y) {
  return {static_cast<std::int32_t>(std::floor(x / kCell)), static_cast<std::int32_t>(std::floor(y / kCell))};
}

/// Points every 5 cm over [x0, x1) × [y0, y1) at height z.
void add_plane(PointCloud& out, double x0, double x1, double y0, double y1, double z) {
  for (double x = x0 + 0.025; x < x1; x += 0.05) {
    for (double y = y0 + 0.025; y < y1; y += 0.05) out.emplace_back(x, y, z);
  }
}

/// A vertical face along x = x0 from z0 to z1 over y in [y0, y1).
void add_face_x(PointCloud& out, double x0, double y0, double y1, double z0, double z1) {
  for (double y = y0 + 0.025; y < y1; y += 0.05) {
    for (double z = z0; z <= z1 + 1e-9; z += 0.05) out.emplace_back(x0, y, z);
  }
}

TraversabilityTruthParams truth_params() {
  TraversabilityTruthParams p;
  p.cell_size = kCell;
  p.step = 0.2;
  p.robot_height = 2.0;
  p.overhang_cut = 5.0;
  return p;
}

// A 12 cm kerb whose faces go 20 cm into the ground (as the simulator's kerbs do): with the
// walkable ground apart nothing of it blocks; with the lowest point as ground the buried foot lifts
// the sidewalk beside it over the step.
TEST(TrueTraversabilityTest, BuriedKerbFaceDoesNotBlockWhenTheGroundIsKnown) {
  PointCloud ground;
  add_plane(ground, 0.0, 3.0, 0.0, 2.0, 0.0);    // road, x < 3
  add_plane(ground, 3.25, 6.0, 0.0, 2.0, 0.12);  // sidewalk, x >= 3.25
  PointCloud surface = ground;
  add_plane(surface, 3.0, 3.25, 0.0, 2.0, 0.12);          // kerb top
  add_face_x(surface, 3.0, 0.0, 2.0, -0.2, 0.12);         // kerb face toward the road, partly buried
  add_face_x(surface, 3.25, 0.0, 2.0, -0.2, 0.12);        // the face under the sidewalk: buried
  const TrueTraversability with_ground = true_traversability(surface, ground, truth_params());
  const TrueTraversability lowest_only = true_traversability(surface, PointCloud{}, truth_params());
  for (const double x : {2.9, 3.1, 3.3, 3.6}) {
    ASSERT_TRUE(with_ground.contains(key_at(x, 1.0))) << x;
    EXPECT_FALSE(with_ground.at(key_at(x, 1.0)).blocked) << "x " << x;
  }
  // The old rule: the buried foot at -0.2 makes the sidewalk's 0.12 a 0.32 m step.
  EXPECT_TRUE(lowest_only.at(key_at(3.6, 1.0)).blocked);
}

// A box 0.5 m tall on the floor blocks (also its top's inner cells: the floor is within the
// window); a table top at 2.5 m over a 2 m robot is an overhang; a 1 m shelf under the robot's
// height blocks; a roof with no ground anywhere near falls back on the lowest point and blocks nothing.
TEST(TrueTraversabilityTest, BoxBlocksTableOverhangsRoofWithoutGroundIsItsOwnGround) {
  PointCloud ground;
  add_plane(ground, 0.0, 10.0, 0.0, 4.0, 0.0);
  PointCloud surface = ground;
  add_plane(surface, 1.0, 1.5, 1.0, 1.5, 0.5);   // box top
  add_plane(surface, 4.0, 5.0, 1.0, 2.0, 2.5);   // table top over the robot
  add_plane(surface, 7.0, 7.5, 1.0, 1.5, 1.0);   // shelf within the robot's height
  add_plane(surface, 30.0, 31.0, 0.0, 1.0, 9.0); // a roof, far from any ground
  const TrueTraversability t = true_traversability(surface, ground, truth_params());
  EXPECT_TRUE(t.at(key_at(1.1, 1.1)).blocked);
  EXPECT_TRUE(t.at(key_at(1.4, 1.4)).blocked);
  EXPECT_FALSE(t.at(key_at(4.5, 1.5)).blocked);
  EXPECT_TRUE(t.at(key_at(4.5, 1.5)).overhang);
  EXPECT_TRUE(t.at(key_at(7.1, 1.1)).blocked);
  EXPECT_FALSE(t.at(key_at(7.1, 1.1)).overhang);
  EXPECT_FALSE(t.at(key_at(30.5, 0.5)).blocked);
  EXPECT_FALSE(t.at(key_at(30.5, 0.5)).overhang);
  EXPECT_FALSE(t.at(key_at(8.6, 3.1)).blocked);  // open floor
  // Above the cut a surface is no overhang: the same table at 6 m.
  PointCloud high = ground;
  add_plane(high, 4.0, 5.0, 1.0, 2.0, 6.0);
  EXPECT_FALSE(true_traversability(high, ground, truth_params()).at(key_at(4.5, 1.5)).overhang);
  // Empty and non-finite input.
  EXPECT_TRUE(true_traversability({}, {}, truth_params()).empty());
  PointCloud bad{{std::nanf(""), 0.0F, 0.0F}, {0.0F, std::numeric_limits<float>::infinity(), 0.0F}};
  EXPECT_TRUE(true_traversability(bad, bad, truth_params()).empty());
}

// Hand-counted: four truth cells, a grid deciding three of them (one undecided at 0.5).
TEST(ScoreGridTest, CountsWithMapServersThresholds) {
  TrueTraversability truth;
  truth[{0, 0}] = {true, false};   // blocked, grid says occupied: found
  truth[{1, 0}] = {true, false};   // blocked, grid says free: missed
  truth[{2, 0}] = {false, true};   // overhang, grid says free: kept free
  truth[{3, 0}] = {false, false};  // free, grid undecided: not compared
  truth[{4, 0}] = {false, false};  // free, grid does not know it
  OccupancyGrid grid(kCell, 0.12, 0.97);
  grid.set({0, 0}, log_odds(0.9));
  grid.set({1, 0}, log_odds(0.15));
  grid.set({2, 0}, log_odds(0.19));   // just under map_server's free threshold
  grid.set({3, 0}, log_odds(0.5));
  const GridScores s = score_grid(grid, truth);
  EXPECT_EQ(s.compared, 3U);
  EXPECT_EQ(s.blocked, 2U);
  EXPECT_EQ(s.blocked_found, 1U);
  EXPECT_EQ(s.free, 1U);
  EXPECT_EQ(s.free_found, 1U);
  EXPECT_EQ(s.overhang, 1U);
  EXPECT_EQ(s.overhang_free, 1U);
  EXPECT_DOUBLE_EQ(s.accuracy(), 2.0 / 3.0);
  // Scoped to cell i = 0 only.
  const GridScores only = score_grid(grid, truth, [](const CellKey& k) { return k.i == 0; });
  EXPECT_EQ(only.compared, 1U);
  EXPECT_EQ(only.blocked_found, 1U);
  EXPECT_EQ(score_grid(OccupancyGrid(kCell, 0.12, 0.97), truth).compared, 0U);
}

/// A street: parked cars beside the lane, a facade behind them, trees whose crowns (bottom 2.6 m)
/// reach over the road. The rays to the facade and to the crowns cross the cars in 2D.
sim::Scene street() {
  sim::SceneBuilder b;
  b.add("road", sim::make_ground({-20.0, -20.0}, {40.0, 20.0}, 0.0));
  for (const double x : {4.0, 10.0, 16.0}) b.add("car", sim::make_car(), sim::Placement{{x, 3.0, 0.0}, 0.0});
  b.add("facade", sim::make_wall({-10.0, 8.0}, {30.0, 8.0}, 8.0));
  sim::TreeSize tree;
  tree.crown_bottom = 2.6;
  for (const double x : {7.0, 13.0}) b.add("tree", sim::make_tree(tree), sim::Placement{{x, -4.0, 0.0}, 0.0});
  return b.build();
}

GridScores drive_and_score(double free_ray_height) {
  const sim::Scene world = street();
  Params p = outdoor_preset();
  p.map.max_range = 20.0;
  p.occupancy.free_ray_height = free_ray_height;
  sim::SpinningLidarParams lp = sim::SpinningLidarParams::vlp16();
  lp.azimuth_step_deg = 0.4;
  sim::SpinningLidar lidar(lp);
  HybridMapper mapper(p);
  for (int k = 0; k < 12; ++k) {
    Pose T = Pose::Identity();
    T.translation() = Eigen::Vector3d(-2.0 + 2.0 * k, 0.0, 1.73);
    mapper.integrate(lidar.scan(world, T, 0.0).points_sensor, T);
  }
  std::mt19937_64 rng(7);
  const sim::Scene::KindedSample sample = world.sample_surface_kinds(0.05, rng, 0.0);
  PointCloud surface, ground;
  for (std::size_t n = 0; n < sample.points.size(); ++n) {
    const Point3f& q = sample.points[n];
    if (q.x() < -2.0 || q.x() > 22.0 || q.y() < -7.0 || q.y() > 7.0) continue;  // the part the drive sees well
    surface.push_back(q);
    if (sample.kinds[n] == sim::SurfaceKind::kGround) ground.push_back(q);
  }
  const TrueTraversability truth = true_traversability(surface, ground, truth_params());
  return score_grid(mapper.grid(), truth);
}

// The grid kept scan by scan (eq. 3-4): a pass frees a cell only where the ray runs low over it.
// With the paper's 2D ray (every crossed cell freed) the rays to the facade and the crowns wipe out
// the parked cars.
TEST(KeptGridTest, RaysOverParkedCarsDoNotFreeThem) {
  const GridScores low = drive_and_score(0.2);
  const GridScores paper = drive_and_score(100.0);
  std::printf("blocked %zu found %.3f (paper %.3f); free %.3f (%.3f); overhang %zu free %.3f (%.3f)\n", low.blocked,
              low.blocked_recall(), paper.blocked_recall(), low.free_recall(), paper.free_recall(), low.overhang,
              low.overhang_accuracy(), paper.overhang_accuracy());
  ASSERT_GT(low.blocked, 60U);
  ASSERT_GT(low.overhang, 50U);
  EXPECT_GT(low.blocked_recall(), 0.6) << low.blocked_found << " of " << low.blocked;
  EXPECT_GT(low.blocked_recall(), paper.blocked_recall() + 0.2)
      << "low " << low.blocked_recall() << " paper " << paper.blocked_recall();
  EXPECT_GT(low.free_recall(), 0.97);
  EXPECT_GT(low.overhang_accuracy(), 0.95);  // the road under the crowns stays free
}

}  // namespace
}  // namespace hmap
