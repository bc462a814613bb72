#include "hmap/occupancy/occupancy_update.hpp"

#include <gtest/gtest.h>

#include <optional>
#include <tuple>

#include <cmath>

namespace hmap {
namespace occupancy_update_test {

Params params() {
  Params p = indoor_preset();
  p.map.cell_size = 0.1;
  p.occupancy.z_plus = 0.5;  // a robot 0.5 m tall passes under tables
  p.occupancy.z_minus = -0.2;
  return p;
}

GroundModel flat_ground() {
  return GroundModel({GroundPatch{{0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 100.0, -1}});
}

HVoxel hv(float lo, float hi, float density) { return {lo, hi, 10.0F, density}; }

TEST(OccupancyUpdateTest, RolesByHand) {
  const OccupancyParams op = params().occupancy;  // z+ 0.5, z− −0.2, d_pth 0.03
  EXPECT_EQ(hvoxel_role(hv(0.7F, 0.75F, 0.9F), 0.0, op), HVoxelRole::kIgnored);   // table top above z+
  EXPECT_EQ(hvoxel_role(hv(-0.6F, -0.4F, 0.9F), 0.0, op), HVoxelRole::kIgnored);  // a pit below z−
  EXPECT_EQ(hvoxel_role(hv(0.0F, 2.0F, 0.9F), 0.0, op), HVoxelRole::kObstacle);   // wall
  EXPECT_EQ(hvoxel_role(hv(0.3F, 0.45F, 0.9F), 0.0, op), HVoxelRole::kObstacle);  // a box under z+
  EXPECT_EQ(hvoxel_role(hv(-0.01F, 0.01F, 0.9F), 0.0, op), HVoxelRole::kGround);
  EXPECT_EQ(hvoxel_role(hv(1.01F, 1.02F, 0.9F), 1.0, op), HVoxelRole::kGround);   // relative to the patch
}

TEST(OccupancyUpdateTest, InverseSensorModelByHand) {
  const OccupancyParams op = params().occupancy;  // σ 0.02, K_g 0.3, d_pth 0.03
  EXPECT_DOUBLE_EQ(inverse_sensor_model(HVoxelRole::kObstacle, 0.9, 0.0, op), 0.9);
  EXPECT_DOUBLE_EQ(inverse_sensor_model(HVoxelRole::kObstacle, 0.2, 0.0, op), 0.5);  // max(ρ, 0.5)
  EXPECT_NEAR(inverse_sensor_model(HVoxelRole::kObstacle, 0.9, 0.02, op), 0.9 * std::exp(-0.5), 1e-12);
  EXPECT_DOUBLE_EQ(inverse_sensor_model(HVoxelRole::kGround, 0.9, 0.0, op), 0.3 + 0.2 / 2.0);
  EXPECT_NEAR(inverse_sensor_model(HVoxelRole::kGround, 0.9, -1.0, op), 0.3, 1e-12);
  EXPECT_DOUBLE_EQ(inverse_sensor_model(HVoxelRole::kIgnored, 0.9, 0.0, op), 0.5);
}

// A sensor at (0.05, 0.05, 1) sees: a wall cell at x = 3, the floor along the way, a table top
// (above z+) over floor at (1.55, 1.05), and a ceiling patch at (2.05, -0.95).
TEST(OccupancyUpdateTest, WallOccupiedFloorFreeTableAndCeilingIgnored) {
  ScanHVoxels scan;
  scan.origin_map = {0.05, 0.05, 1.0};
  auto add = [&](CellKey key, std::vector<HVoxel> vs) {
    scan.cells.push_back({key, static_cast<std::uint32_t>(scan.hvoxels.size()), static_cast<std::uint32_t>(vs.size())});
    for (const auto& v : vs) scan.hvoxels.push_back(v);
  };
  add({30, 0}, {hv(0.0F, 2.0F, 0.95F)});                          // wall
  for (int i = 5; i < 30; ++i) add({i, 0}, {hv(0.0F, 0.01F, 0.9F)});  // floor in front of it
  add({15, 10}, {hv(-0.005F, 0.005F, 0.9F), hv(0.7F, 0.75F, 0.9F)});  // floor + table top
  add({20, -10}, {hv(2.5F, 2.6F, 0.9F)});                        // ceiling only
  OccupancyGrid grid(0.1, 0.12, 0.97);
  const auto stats = update_occupancy(scan, flat_ground(), params(), grid);
  EXPECT_EQ(stats.rays, scan.cells.size() - 1);  // the ceiling cell casts no ray
  ASSERT_TRUE(grid.probability_at({30, 0}));
  EXPECT_GT(*grid.probability_at({30, 0}), 0.9);  // the wall: ρ = 0.95
  for (int i = 5; i < 30; ++i) {
    ASSERT_TRUE(grid.probability_at({i, 0})) << i;
    EXPECT_LT(*grid.probability_at({i, 0}), 0.5) << i;  // drivable floor
  }
  ASSERT_TRUE(grid.probability_at({15, 10}));
  EXPECT_LT(*grid.probability_at({15, 10}), 0.5);  // under the table: free for a 0.5 m robot
  EXPECT_FALSE(grid.probability_at({20, -10}).has_value());  // the ceiling says nothing
  // Repeated scans make the evidence firmer, up to the clamp.
  for (int k = 0; k < 40; ++k) update_occupancy(scan, flat_ground(), params(), grid);
  EXPECT_NEAR(*grid.probability_at({30, 0}), 0.97, 1e-6);
  EXPECT_NEAR(*grid.probability_at({10, 0}), 0.12, 1e-6);  // each scan adds log-odds of <= 0.4: down to the clamp
}

TEST(OccupancyUpdateTest, NoGroundNoEvidence) {
  ScanHVoxels scan;
  scan.cells.push_back({{3, 3}, 0, 1});
  scan.hvoxels.push_back(hv(0.0F, 1.0F, 0.9F));
  OccupancyGrid grid(0.1, 0.12, 0.97);
  const auto stats = update_occupancy(scan, GroundModel(), params(), grid);
  EXPECT_EQ(stats.no_ground, 1U);
  EXPECT_EQ(grid.known_cells(), 0U);
}

// The stretch of a linear clearance under a limit, by hand: from 1.7 m down to 0 under 0.2 m is
// t >= 1.5/1.7; rising from 0.1 to 1.1 under 0.6 is t <= 0.5; both ends under: all; neither: none.
TEST(BelowAlongTest, StretchOfALinearHeightUnderALimit) {
  auto [lo, hi] = below_along(1.7, 0.0, 0.2);
  EXPECT_NEAR(lo, 1.5 / 1.7, 1e-12);
  EXPECT_EQ(hi, 1.0);
  std::tie(lo, hi) = below_along(0.1, 1.1, 0.6);
  EXPECT_EQ(lo, 0.0);
  EXPECT_NEAR(hi, 0.5, 1e-12);
  std::tie(lo, hi) = below_along(0.1, 0.15, 0.2);
  EXPECT_EQ(lo, 0.0);
  EXPECT_EQ(hi, 1.0);
  std::tie(lo, hi) = below_along(1.7, 0.5, 0.2);
  EXPECT_GT(lo, hi);
  std::tie(lo, hi) = below_along(0.3, 0.3, 0.3);  // on the limit counts as under
  EXPECT_EQ(lo, 0.0);
  EXPECT_EQ(hi, 1.0);
}

}  // namespace occupancy_update_test
}  // namespace hmap

namespace hmap {
namespace occupancy_update_test {

// The grid judged from a finished map (export --pgm), beyond the ground's reach: a wall whose foot
// stands on the nearest patch's plane is blocked, anything else stays unknown (balm_os0's west
// wall, whose floor the sensor saw too sparsely for patches).
TEST(OccupancyFromMapTest, BeyondTheGroundsReachOnlyObstaclesStandingOnItsPlaneAreBlocked) {
  Params p = indoor_preset();
  p.map.cell_size = 0.1;
  p.occupancy.z_plus = 2.0;
  p.occupancy.z_minus = -0.5;
  p.occupancy.ground_reach = 3.0;
  p.occupancy.obstacle_reach = 15.0;
  p.ground.elevation_threshold = 0.1;
  // One patch at the origin on a plane rising 2 % along x: z = 0.02 x.
  const GroundModel ground({GroundPatch{{0.0, 0.0, 0.0}, Eigen::Vector3d(-0.02, 0.0, 1.0).normalized(), 0.5, -1}});
  HMap map(p);
  const auto put = [&](double x, double y, std::vector<HVoxel> vs) {
    const CellKey key = *map.key_of(x, y);
    TileColumn column = map.column_for_update(key);
    for (const HVoxel& v : vs) column.insert(column.size(), v);
    return key;
  };
  const auto z = [](double x) { return static_cast<float>(0.02 * x); };
  // Within reach (2 m): the paper's rules, a wall blocked and bare floor free.
  const CellKey near_wall = put(2.05, 0.05, {hv(z(2.05), 1.5F, 0.9F)});
  const CellKey near_floor = put(2.05, 1.05, {hv(z(2.05), z(2.05) + 0.01F, 0.9F)});
  // Beyond reach (8 m) but within obstacle_reach:
  const CellKey foot = put(8.05, 0.05, {hv(z(8.05) + 0.05F, 1.5F, 0.9F)});                // on the plane: blocked
  const CellKey floor_far = put(8.05, 1.05, {hv(z(8.05), z(8.05) + 0.01F, 0.9F)});        // bare floor: unknown
  const CellKey hanging = put(8.05, 2.05, {hv(z(8.05) + 0.3F, 1.5F, 0.9F)});              // 0.3 m up: unknown
  const CellKey lower = put(8.05, 3.05, {hv(z(8.05) - 1.0F, z(8.05) - 0.2F, 0.9F)});      // on a floor 1 m down
  const CellKey stacked = put(8.05, 4.05, {hv(z(8.05), z(8.05) + 0.01F, 0.9F), hv(1.0F, 1.5F, 0.9F)});  // floor under a shelf: blocked
  // Beyond obstacle_reach (20 m): a wall on the plane stays unknown.
  const CellKey far_wall = put(20.05, 0.05, {hv(z(20.05), 1.5F, 0.9F)});
  // A flat extrapolation (the patch's centre height, 0) would put this foot 0.16 m off: the plane's own height is used.
  ASSERT_GT(z(8.05), p.ground.elevation_threshold);

  const OccupancyGrid grid = occupancy_from_map(map, ground, p, p.occupancy.ground_reach);
  const float hi = grid.clamp_max_log_odds();
  const float lo = grid.clamp_min_log_odds();
  EXPECT_EQ(grid.log_odds_at(near_wall), std::optional<float>(hi));
  EXPECT_EQ(grid.log_odds_at(near_floor), std::optional<float>(lo));
  EXPECT_EQ(grid.log_odds_at(foot), std::optional<float>(hi));
  EXPECT_FALSE(grid.log_odds_at(floor_far).has_value()) << "never free beyond the ground's reach";
  EXPECT_FALSE(grid.log_odds_at(hanging).has_value());
  EXPECT_FALSE(grid.log_odds_at(lower).has_value());
  EXPECT_EQ(grid.log_odds_at(stacked), std::optional<float>(hi)) << "the floor puts it on the plane, the shelf blocks";
  EXPECT_FALSE(grid.log_odds_at(far_wall).has_value());

  // The reach is the parameter's: at 25 m the far wall is blocked too, at 5 m the foot is not.
  p.occupancy.obstacle_reach = 25.0;
  EXPECT_EQ(occupancy_from_map(map, ground, p, p.occupancy.ground_reach).log_odds_at(far_wall), std::optional<float>(hi));
  p.occupancy.obstacle_reach = 5.0;
  EXPECT_FALSE(occupancy_from_map(map, ground, p, p.occupancy.ground_reach).log_odds_at(foot).has_value());
}

}  // namespace occupancy_update_test
}  // namespace hmap
