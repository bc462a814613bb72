#include "hmap/occupancy/hybrid_mapper.hpp"

#include <gtest/gtest.h>

#include "hmap/sim/composites.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap {
namespace {

/// Flat ground, a wall across x = 10, a tree whose crown (bottom 2.2 m) overhangs the ground
/// around (5, 4), and a ceiling slab (underside 2.5 m) over x in [-7, -4].
sim::Scene scene() {
  sim::SceneBuilder b;
  b.add("ground", sim::make_ground({-30.0, -30.0}, {30.0, 30.0}, 0.0));
  b.add("wall", sim::make_wall({10.0, -6.0}, {10.0, 6.0}, 2.5));
  sim::TreeSize tree;
  tree.crown_bottom = 2.2;  // above z+ = 2 m, low enough for the VLP-16's +15° beams to see
  tree.crown_height = 1.6;
  b.add("tree", sim::make_tree(tree), sim::Placement{{5.0, 4.0, 0.0}, 0.0});
  b.add("ceiling", sim::make_ceiling({-7.0, -3.0}, {-4.0, 3.0}, 2.5));
  return b.build();
}

Params params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.2;
  p.map.max_range = 20.0;
  p.map.min_range = 0.5;
  return p;
}

double p_at(const OccupancyGrid& grid, double x, double y) {
  const CellKey key{static_cast<std::int32_t>(std::floor(x / grid.cell_size())),
                    static_cast<std::int32_t>(std::floor(y / grid.cell_size()))};
  return grid.probability_at(key).value_or(-1.0);
}

TEST(HybridMapperTest, WallOccupiedGroundUnderCrownAndCeilingFree) {
  const sim::Scene world = scene();
  sim::SpinningLidarParams lp = sim::SpinningLidarParams::vlp16();
  lp.azimuth_step_deg = 0.4;
  sim::SpinningLidar lidar(lp);
  HybridMapper mapper(params());
  for (int k = 0; k < 6; ++k) {
    Pose T_world_sensor = Pose::Identity();
    T_world_sensor.translation() = Eigen::Vector3d(-3.0 + 1.5 * k, -1.0, 1.8);
    const sim::SimulatedScan scan = lidar.scan(world, T_world_sensor, 0.1 * k);
    const HybridScanStats s = mapper.integrate(scan.points_sensor, T_world_sensor);
    EXPECT_GT(s.map.points_kept, 1000U);
    EXPECT_GT(s.occupancy.cells, 100U);
  }
  // The ground tree covers the flat ground at z = 0 under the sensor's reach.
  ASSERT_GT(mapper.ground_patches().size(), 50U);
  for (const GroundPatch& g : mapper.ground_patches()) EXPECT_NEAR(g.center.z(), 0.0, 0.1);
  const OccupancyGrid& grid = mapper.grid();
  // The wall: occupied along its face (eq. 4 gives max(ρ, 0.5) at a hit: faint for sparse walls).
  for (double y = -3.0; y <= 3.0; y += 1.0) EXPECT_GT(p_at(grid, 9.9, y + 0.1), 0.55) << "wall face at y " << y;
  // Open ground: free.
  EXPECT_LT(p_at(grid, 2.1, -1.1), 0.3);
  EXPECT_LT(p_at(grid, 7.1, -3.1), 0.3);
  // Under the tree crown (above z+) and away from the trunk: free, as the paper wants.
  EXPECT_LT(p_at(grid, 5.1, 2.3), 0.3);
  EXPECT_LT(p_at(grid, 3.5, 4.1), 0.3);
  // The trunk itself is an obstacle: its face seen from the south.
  double trunk = 0.0;
  for (double dx = -0.2; dx <= 0.2; dx += 0.2) {
    for (double dy = -0.2; dy <= 0.2; dy += 0.2) trunk = std::max(trunk, p_at(grid, 5.01 + dx, 4.01 + dy));
  }
  EXPECT_GT(trunk, 0.7);
  // Under the ceiling slab: free.
  EXPECT_LT(p_at(grid, -5.5, 0.1), 0.3);
  // The HVoxels of the crown and the ceiling are in the 3D map all the same.
  const auto column_has = [&](double x, double y, double z0, double z1) {
    for (double z = z0; z <= z1; z += 0.05) {
      if (mapper.map().occupied(x, y, z)) return true;
    }
    return false;
  };
  // The crown over the free cells: seen, in the 3D map, ignored by the 2D grid.
  EXPECT_TRUE(column_has(5.1, 2.3, 2.2, 4.0) || column_has(3.5, 4.1, 2.2, 4.0));
  int ceiling_cells = 0;  // the underside, where the +11..15° beams reach it
  for (double x = -6.9; x < -4.0; x += 0.2) {
    for (double y = -2.9; y < 3.0; y += 0.2) ceiling_cells += column_has(x, y, 2.4, 2.6) ? 1 : 0;
  }
  EXPECT_GT(ceiling_cells, 20);
}

TEST(HybridMapperTest, ContinuesFromSavedLayers) {
  const sim::Scene world = scene();
  sim::SpinningLidar lidar(sim::SpinningLidarParams::vlp16());
  HybridMapper first(params());
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(0.0, 0.0, 1.0);
  const PointCloud points = lidar.scan(world, T, 0.0).points_sensor;
  first.integrate(points, T);
  const std::size_t patches = first.ground_patches().size();
  ASSERT_GT(patches, 0U);
  Mapper same(params());  // the same HMAP again (maps are move-only)
  same.integrate(points, T);
  OccupancyGrid grid(first.grid().cell_size(), 0.12, 0.97);
  first.grid().for_each_cell([&](const CellKey& key, float l) { grid.set(key, l); });
  HybridMapper resumed(std::move(same.map()), std::move(grid), first.ground_patches());
  EXPECT_EQ(resumed.ground_patches().size(), patches);
  EXPECT_EQ(resumed.grid().known_cells(), first.grid().known_cells());
  const HybridScanStats s = resumed.integrate(lidar.scan(world, T, 0.1).points_sensor, T);
  EXPECT_FALSE(s.ground.seeded);
}

}  // namespace
}  // namespace hmap
