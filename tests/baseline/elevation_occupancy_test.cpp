#include "hmap/baseline/elevation_occupancy.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "hmap/baseline/elevation_mapper.hpp"
#include "hmap/occupancy/occupancy_update.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap {
namespace elevation_occupancy_test {

Params table_params() {
  Params p = indoor_preset();  // d_pth 0.03
  p.map.cell_size = 0.1;
  p.map.min_range = 0.1;
  p.map.max_range = 10.0;
  return p;
}

Pose at(double x, double y, double z) {
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

GroundModel flat_ground() { return GroundModel({GroundPatch{{1.5, 1.5, 0.0}, {0.0, 0.0, 1.0}, 100.0, -1}}); }

// Seen from a sensor at (1.5, 1.5, 2): the floor z = 0 over [0, 3]² every 2.5 cm; the top of a
// table at 0.75 m over [1, 1.8]² (second scan).
std::pair<PointCloud, PointCloud> table_scans() {
  PointCloud floor_sensor;
  PointCloud top_sensor;
  for (int a = 0; a < 120; ++a) {
    for (int b = 0; b < 120; ++b) {
      const float x = 0.0125F + 0.025F * static_cast<float>(a);
      const float y = 0.0125F + 0.025F * static_cast<float>(b);
      floor_sensor.emplace_back(x - 1.5F, y - 1.5F, -2.0F);
      if (x > 1.0F && x < 1.8F && y > 1.0F && y < 1.8F) top_sensor.emplace_back(x - 1.5F, y - 1.5F, -1.25F);
    }
  }
  return {floor_sensor, top_sensor};
}

TEST(ElevationOccupancyTest, RolesByHand) {
  const OccupancyParams op = table_params().occupancy;  // d_pth 0.03, z− −0.2
  EXPECT_EQ(elevation_role(0.75, 0.0, op), ElevationRole::kObstacle);  // a table top, above z+ or not
  EXPECT_EQ(elevation_role(5.0, 0.0, op), ElevationRole::kObstacle);   // a tree crown
  EXPECT_EQ(elevation_role(0.02, 0.0, op), ElevationRole::kGround);
  EXPECT_EQ(elevation_role(-0.03, 0.0, op), ElevationRole::kGround);   // d_pth inclusive
  EXPECT_EQ(elevation_role(-0.1, 0.0, op), ElevationRole::kDrop);
  EXPECT_EQ(elevation_role(-0.7, 0.0, op), ElevationRole::kDrop);      // a pit below z−
  EXPECT_EQ(elevation_role(1.01, 1.0, op), ElevationRole::kGround);    // relative to the patch
}

TEST(ElevationOccupancyTest, TableTopOccupiedFloorFree) {
  const Params p = table_params();
  ElevationMapper mapper(p);
  const auto [floor_sensor, top_sensor] = table_scans();
  mapper.integrate(floor_sensor, at(1.5, 1.5, 2.0));
  const auto s = mapper.integrate(top_sensor, at(1.5, 1.5, 2.0));
  EXPECT_EQ(s.replaced, 64U);  // the 8 × 8 cells of the table top
  const ElevationMap& map = mapper.map();
  EXPECT_EQ(map.known_cells(), 900U);
  EXPECT_DOUBLE_EQ(*map.elevation_at(1.45, 1.25), 0.75F);
  EXPECT_DOUBLE_EQ(*map.elevation_at(0.5, 2.5), 0.0F);
  EXPECT_FLOAT_EQ(map.find(1.45, 1.25)->lowest, 0.0F);  // the floor seen first

  const OccupancyGrid grid = occupancy_from_elevation(map, flat_ground(), p, 10.0);
  EXPECT_EQ(grid.known_cells(), 900U);
  std::size_t occupied = 0;
  grid.for_each_cell([&](const CellKey& key, float l) {
    const Eigen::Vector2d xy = map.cell_center(key);
    const bool under_table = xy.x() > 1.0 && xy.x() < 1.8 && xy.y() > 1.0 && xy.y() < 1.8;
    EXPECT_EQ(l, under_table ? grid.clamp_max_log_odds() : grid.clamp_min_log_odds()) << xy.transpose();
    occupied += under_table ? 1 : 0;
  });
  EXPECT_EQ(occupied, 64U);
  EXPECT_FALSE(grid.log_odds_at({40, 40}));  // never observed

  // Without a patch near enough, nothing is known.
  const GroundModel far({GroundPatch{{50.0, 50.0, 0.0}, {0.0, 0.0, 1.0}, 0.5, -1}});
  EXPECT_EQ(occupancy_from_elevation(map, far, p, 10.0).known_cells(), 0U);
  EXPECT_EQ(occupancy_from_elevation(map, GroundModel(), p, 10.0).known_cells(), 0U);
}

// The HMAP's answer on the same input, for contrast: an HVoxel at 0.75 m is above z+ = 0.5 and
// says nothing; the 2.5D map calls it an obstacle. (HMAP keeps the floor under it too.)
TEST(ElevationOccupancyTest, OverhangIsAWallInTwoPointFiveD) {
  Params p = table_params();
  p.occupancy.z_plus = 0.5;
  ElevationMapper mapper(p);
  const auto [floor_sensor, top_sensor] = table_scans();
  mapper.integrate(floor_sensor, at(1.5, 1.5, 2.0));
  mapper.integrate(top_sensor, at(1.5, 1.5, 2.0));
  const HVoxel top{0.71F, 0.75F, 10.0F, 1.0F};
  EXPECT_EQ(hvoxel_role(top, 0.0, p.occupancy), HVoxelRole::kIgnored);
  const OccupancyGrid grid = occupancy_from_elevation(mapper.map(), flat_ground(), p, 10.0);
  EXPECT_EQ(*grid.log_odds_at(*mapper.map().key_of(1.45, 1.25)), grid.clamp_max_log_odds());
}

TEST(ElevationOccupancyTest, AsHMapRoundTrip) {
  ElevationMap map(table_params());
  map.cell_for_update({0, 0}) = {0.5F, 0.01F, 0.1F, 7};
  map.cell_for_update({-3, 12}) = {-1.25F, 0.02F, -1.5F, 1};
  map.cell_for_update({100000, -5}) = {3.0F, 0.03F, 3.0F, 40};
  const HMap h = as_hmap(map);
  EXPECT_DOUBLE_EQ(h.cell_size(), map.cell_size());
  EXPECT_EQ(h.stats().cells, 3U);
  EXPECT_EQ(h.stats().hvoxels, 3U);
  map.for_each_cell([&](const CellKey& key, const ElevationCell& c) {
    const ColumnView column = h.column(key);
    ASSERT_EQ(column.size(), 1U);
    const HVoxel& v = column[0];
    EXPECT_EQ(v.z_min, c.elevation);
    EXPECT_EQ(v.z_max, c.elevation);
    EXPECT_EQ(v.count, static_cast<float>(c.points));
    EXPECT_FLOAT_EQ(v.density, hvoxel_density(c.points, 0.0, map.params().map));
  });
  EXPECT_TRUE(as_hmap(ElevationMap(table_params())).empty());
}

// The built-in office, three lidar scans from 1.3 m around table 1 (x in [2.2, 3.8], y in
// [1.6, 2.4], top at 0.75 m), ground by our RRT on the 2.5D map: the cells under the table top
// are occupied, the free floor in front of it free.
TEST(ElevationOccupancyTest, OfficeTableOccupiedFloorFree) {
  const sim::Scene scene = sim::make_office_scene();
  sim::SpinningLidarParams lp;
  for (int e = -45; e <= -5; ++e) lp.elevations_deg.push_back(e);
  lp.azimuth_step_deg = 0.5;
  lp.min_range = 0.3;
  lp.max_range = 6.0;
  lp.range_sigma = 0.005;
  lp.dropout_probability = 0.0;
  lp.seed = 7;
  sim::SpinningLidar lidar(lp);
  Params p = indoor_preset();
  p.map.cell_size = 0.1;
  p.map.min_range = 0.3;
  p.map.max_range = 6.0;
  ElevationMapper mapper(p);
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(3.0, 1.0), Eigen::Vector2d(1.5, 2.0), Eigen::Vector2d(4.5, 2.0)}) {
    const Pose T = at(xy.x(), xy.y(), 1.3);
    mapper.integrate(lidar.scan(scene, T, 0.0).points_sensor, T);
  }
  const ElevationMap& map = mapper.map();
  const GroundResult ground = extract_ground(as_hmap(map), {3.0, 1.0, 1.3}, p.ground);
  ASSERT_TRUE(ground.seeded);
  const GroundModel model(ground.patches);
  for (const GroundPatch& patch : ground.patches) EXPECT_LT(patch.center.z(), 0.1);  // no patch on a table
  const OccupancyGrid grid = occupancy_from_elevation(map, model, p, 1.0);

  std::size_t table_cells = 0, table_occupied = 0, floor_cells = 0, floor_free = 0;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 30; ++j) {
      const CellKey key{i, j};
      const Eigen::Vector2d c = map.cell_center(key);
      const auto l = grid.log_odds_at(key);
      if (c.x() > 2.3 && c.x() < 3.7 && c.y() > 1.7 && c.y() < 2.3) {
        ++table_cells;
        if (l && *l == grid.clamp_max_log_odds()) ++table_occupied;
        if (const ElevationCell* e = map.find(key)) {
          EXPECT_NEAR(e->elevation, 0.75, 0.03) << c.transpose();
        }
      } else if (c.x() > 1.0 && c.x() < 5.0 && c.y() > 0.3 && c.y() < 1.3) {
        ++floor_cells;
        if (l && *l == grid.clamp_min_log_odds()) ++floor_free;
        if (l) {
          EXPECT_EQ(*l, grid.clamp_min_log_odds()) << c.transpose();
        }
      }
    }
  }
  EXPECT_EQ(table_cells, 14U * 6U);
  EXPECT_GE(table_occupied, table_cells * 9 / 10);
  EXPECT_EQ(floor_cells, 40U * 10U);
  EXPECT_GE(floor_free, floor_cells * 8 / 10);
}

}  // namespace elevation_occupancy_test
}  // namespace hmap
