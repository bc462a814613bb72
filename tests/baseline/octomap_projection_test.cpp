#include "hmap/baseline/octomap_projection.hpp"

#include <gtest/gtest.h>

namespace hmap {
namespace {

constexpr double kRes = 0.25;

std::optional<double> p_at(const OccupancyGrid& g, double x, double y) {
  return g.probability_at({static_cast<std::int32_t>(std::floor(x / kRes)), static_cast<std::int32_t>(std::floor(y / kRes))});
}

void set(octomap::OcTree& tree, double x, double y, double z, bool occupied) {
  tree.updateNode(octomap::point3d(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)),
                  occupied ? tree.getClampingThresMaxLog() : tree.getClampingThresMinLog());
}

// By hand, on a flat ground at z = 1 (a patch 10 m wide): the band is 0.2..2 m above it.
TEST(OctomapProjectionTest, BandAboveTheLocalGroundOccupiedOverFree) {
  octomap::OcTree tree(kRes);
  set(tree, 0.1, 0.1, 1.1, true);    // the ground's own leaf (centre 0.125 above): out of the band
  set(tree, 0.1, 0.1, 1.6, false);   // free above it: the cell is free
  set(tree, 1.1, 0.1, 1.6, true);    // a box: occupied
  set(tree, 1.1, 0.1, 2.4, false);   // free above the box: occupied wins
  set(tree, 2.1, 0.1, 3.6, true);    // a crown 2.6 m up: out of the band, the cell stays unknown
  set(tree, 3.1, 0.1, 1.6, false);   // free only: free
  set(tree, 30.1, 0.1, 1.6, true);   // far from every ground patch: unknown
  const GroundModel ground({GroundPatch{{0.0, 0.0, 1.0}, Eigen::Vector3d(0.0, 0.0, 1.0), 5.0, -1}});
  OccupancyParams op;
  OctomapProjectionParams band;
  band.min_height = 0.2;
  band.max_height = 2.0;
  band.ground_reach = 6.0;
  const OccupancyGrid grid = project_octomap(tree, ground, kRes, op, band);
  EXPECT_NEAR(p_at(grid, 0.1, 0.1).value_or(-1.0), op.clamp_min, 1e-3);
  EXPECT_NEAR(p_at(grid, 1.1, 0.1).value_or(-1.0), op.clamp_max, 1e-3);
  EXPECT_FALSE(p_at(grid, 2.1, 0.1).has_value());
  EXPECT_NEAR(p_at(grid, 3.1, 0.1).value_or(-1.0), op.clamp_min, 1e-3);
  EXPECT_FALSE(p_at(grid, 30.1, 0.1).has_value());
  EXPECT_EQ(grid.known_cells(), 3U);
  // Nothing in, nothing out; no ground at all: nothing known.
  EXPECT_EQ(project_octomap(octomap::OcTree(kRes), ground, kRes, op, band).known_cells(), 0U);
  EXPECT_EQ(project_octomap(tree, GroundModel(std::vector<GroundPatch>{}), kRes, op, band).known_cells(), 0U);
}

// A pruned leaf of 2x2 cells counts for each of its cells.
TEST(OctomapProjectionTest, PrunedLeafCoversItsCells) {
  octomap::OcTree tree(kRes);
  for (const double x : {0.1, 0.3}) {
    for (const double y : {0.1, 0.3}) {
      for (const double z : {0.6, 0.9}) set(tree, x, y, z, true);  // a 0.5 m cube [0, 0.5] x [0, 0.5] x [0.5, 1.0]
    }
  }
  tree.prune();
  const GroundModel ground({GroundPatch{{0.0, 0.0, 0.0}, Eigen::Vector3d(0.0, 0.0, 1.0), 5.0, -1}});
  const OccupancyGrid grid = project_octomap(tree, ground, kRes, OccupancyParams{}, OctomapProjectionParams{});
  EXPECT_EQ(grid.known_cells(), 4U);
  EXPECT_GT(p_at(grid, 0.4, 0.4).value_or(-1.0), 0.9);
  // As HVoxels: one per cell, 0.5..1.0 m.
  Params params = outdoor_preset();
  const HMap map = octomap_as_hmap(tree, params);
  EXPECT_EQ(map.stats().hvoxels, 4U);
  EXPECT_TRUE(map.occupied(0.1, 0.1, 0.75));
  EXPECT_FALSE(map.occupied(0.1, 0.1, 0.25));
}

}  // namespace
}  // namespace hmap
