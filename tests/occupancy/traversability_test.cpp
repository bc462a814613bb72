#include "hmap/occupancy/traversability.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

constexpr double kCell = 0.25;
constexpr double kPi = 3.14159265358979323846;

/// A flat patch at z = 0 over x in [0, 2), a patch 0.3 m higher over x in [2, 4), a patch sloping
/// 10 degrees over x in [4, 6); all over y in [0, 2).
GroundModel ground() {
  const double t = std::tan(10.0 * kPi / 180.0);
  return GroundModel({GroundPatch{{1.0, 1.0, 0.0}, Eigen::Vector3d(0.0, 0.0, 1.0), 1.0, -1},
                      GroundPatch{{3.0, 1.0, 0.3}, Eigen::Vector3d(0.0, 0.0, 1.0), 1.0, 0},
                      GroundPatch{{5.0, 1.0, 0.0}, Eigen::Vector3d(-t, 0.0, 1.0).normalized(), 1.0, 1}});
}

std::uint8_t cost_at(const TraversabilityLayers& l, double x, double y) {
  const auto col = static_cast<std::int32_t>(std::floor(x / kCell)) - l.i_min;
  const auto row = static_cast<std::int32_t>(std::floor(y / kCell)) - l.j_min;
  return l.cost[l.index(col, row)];
}

/// Every cell of [0, 6) x [0, 2) observed free, then the given changes.
OccupancyGrid free_grid() {
  OccupancyGrid grid(kCell, 0.12, 0.97);
  for (int i = 0; i < 24; ++i) {
    for (int j = 0; j < 8; ++j) grid.set({i, j}, log_odds(0.15));
  }
  return grid;
}

// Hand-computed cells: flat free ground 0; the step between the patches (0.3 m > 0.2 m) lethal on
// both sides of it; the 10 degree slope round(99 * 10 / 20) = 50 (49.5 rounds up); an occupied cell
// 100; an undecided one (p = 0.5) round(99 * (0.5 - 0.196) / (0.65 - 0.196)) = 66.
TEST(TraversabilityTest, CostsFromOccupancyStepAndSlope) {
  OccupancyGrid grid = free_grid();
  grid.set({2, 2}, log_odds(0.9));   // (0.6, 0.6): occupied
  grid.set({4, 6}, log_odds(0.5));   // (1.1, 1.6): undecided
  grid.set({40, 40}, log_odds(0.15));  // far away: free, but no ground there
  TraversabilityParams p;
  const TraversabilityLayers l = traversability(grid, ground(), p);
  ASSERT_EQ(l.i_min, 0);
  ASSERT_EQ(l.width, 41);
  ASSERT_EQ(l.height, 41);
  EXPECT_EQ(cost_at(l, 1.1, 0.6), 0);
  EXPECT_FLOAT_EQ(l.slope_deg[l.index(4, 2)], 0.0F);
  EXPECT_EQ(cost_at(l, 0.6, 0.6), 100);
  EXPECT_EQ(cost_at(l, 1.1, 1.6), 66);
  EXPECT_EQ(cost_at(l, 1.9, 0.6), 100);  // last cell of the low patch, beside the 0.3 m step
  EXPECT_EQ(cost_at(l, 2.1, 0.6), 100);  // first cell of the high patch
  EXPECT_NEAR(l.step[l.index(7, 2)], 0.3, 1e-6);
  EXPECT_EQ(cost_at(l, 2.6, 0.6), 0);    // the high patch's inside is flat
  EXPECT_NEAR(l.slope_deg[l.index(20, 4)], 10.0, 1e-4);
  // Inside the slope: neighbours differ by tan(10 deg) * 0.25 = 0.044 m (step term 0.22 < 0.505).
  EXPECT_EQ(cost_at(l, 5.1, 1.1), 50);
  EXPECT_EQ(cost_at(l, 5.1, 5.1), TraversabilityLayers::kUnknown);  // neither grid nor ground (3.1 m beyond the patch)
  EXPECT_EQ(cost_at(l, 5.1, 4.9), 50);  // no grid, the slope's patch 2.9 m away: the ground's word
  EXPECT_EQ(cost_at(l, 40 * kCell + 0.1, 40 * kCell + 0.1), 0);  // grid free, no ground: the grid's word
  EXPECT_TRUE(std::isnan(l.ground_z[l.index(40, 40)]));
}

// The costmap reads the grid as the exported PGM does (GridReading::for_map at K_g = 0.3: free up to
// 0.3, occupied above 0.65). Hand-computed cells on the flat patch: p = 0.25, which the PGM writes
// free, costs 0 (map_server's 0.196 would give round(99 * 0.054 / 0.454) = 12); p = 0.3, free by the
// reading's slack on the float log-odds, 0; p = 0.5, round(99 * 0.2 / 0.35) = 57; p = 0.6,
// round(99 * 0.3 / 0.35) = 85; p = 0.65, not above the threshold, 99; p = 0.66 lethal.
TEST(TraversabilityTest, ReadsTheGridWithTheExportedThresholds) {
  OccupancyGrid grid = free_grid();
  grid.set({0, 0}, log_odds(0.25));
  grid.set({1, 0}, log_odds(0.3));
  grid.set({2, 0}, log_odds(0.5));
  grid.set({3, 0}, log_odds(0.6));
  grid.set({4, 0}, log_odds(0.65 - 1e-6));
  grid.set({5, 0}, log_odds(0.66));
  OccupancyParams occupancy;
  TraversabilityParams p;
  p.reading = GridReading::for_map(occupancy);
  ASSERT_DOUBLE_EQ(p.reading.free_at_most, 0.3);
  const TraversabilityLayers l = traversability(grid, ground(), p);
  const auto at = [&](int i) { return static_cast<int>(l.cost[l.index(i - l.i_min, -l.j_min)]); };
  EXPECT_EQ(at(0), 0);
  EXPECT_EQ(at(1), 0);
  EXPECT_EQ(at(2), 57);
  EXPECT_EQ(at(3), 85);
  EXPECT_EQ(at(4), 99);
  EXPECT_EQ(at(5), 100);
  // Each cell's class agrees with the reading the PGM is written by: lethal exactly where it says
  // occupied, no grid cost exactly where it says free (the flat patch adds no step or slope).
  for (int i = 0; i <= 5; ++i) {
    const CellClass c = p.reading.classify(*grid.probability_at({i, 0}));
    EXPECT_EQ(at(i) == 100, c == CellClass::kOccupied) << i;
    EXPECT_EQ(at(i) == 0, c == CellClass::kFree) << i;
  }
  // map_server's own thresholds (the default reading) grade the p = 0.25 cell instead.
  const TraversabilityLayers server = traversability(grid, ground(), TraversabilityParams{});
  EXPECT_EQ(static_cast<int>(server.cost[server.index(-server.i_min, -server.j_min)]), 12);
}

// Inflation: 99 exp(-3 d) at the 4-neighbours (d = 0.25: 47) and the diagonals (0.354: 34), nothing
// beyond the radius, lethal and unknown cells untouched.
TEST(TraversabilityTest, InflationAroundLethalCells) {
  OccupancyGrid grid = free_grid();
  grid.set({2, 2}, log_odds(0.9));
  TraversabilityParams p;
  p.inflation_radius = 0.4;
  const TraversabilityLayers l = traversability(grid, ground(), p);
  EXPECT_EQ(cost_at(l, 0.6, 0.6), 100);
  EXPECT_EQ(cost_at(l, 0.85, 0.6), 47);
  EXPECT_EQ(cost_at(l, 0.6, 0.35), 47);
  EXPECT_EQ(cost_at(l, 0.85, 0.85), 34);
  EXPECT_EQ(cost_at(l, 1.1, 0.6), 0);  // d = 0.5 > 0.4
}

TEST(TraversabilityTest, EmptyGridAndBadParameters) {
  const TraversabilityLayers l = traversability(OccupancyGrid(kCell, 0.12, 0.97), ground(), {});
  EXPECT_EQ(l.width, 0);
  EXPECT_TRUE(l.cost.empty());
  TraversabilityParams bad;
  bad.max_slope_deg = 0.0;
  EXPECT_THROW((void)traversability(free_grid(), ground(), bad), Error);
  bad = {};
  bad.inflation_radius = std::nan("");
  EXPECT_THROW(validate(bad), Error);
  bad = {};
  bad.max_step = std::numeric_limits<double>::infinity();
  EXPECT_THROW(validate(bad), Error);
  OccupancyGrid huge(kCell, 0.12, 0.97);
  huge.set({0, 0}, 0.0F);
  huge.set({100000, 100000}, 0.0F);
  EXPECT_THROW((void)traversability(huge, ground(), {}, 1'000'000), Error);
}

}  // namespace
}  // namespace hmap
