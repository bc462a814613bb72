#include <gtest/gtest.h>

#include <cmath>

#include "hmap/core/error.hpp"
#include "hmap/ground/ground_patches.hpp"

namespace hmap {
namespace ground_tracker_test {

constexpr double kCell = 0.1;  // [m]

/// A floor over [x0, x1) × [y0, y1) with tops at height(x, y), one HVoxel per cell.
template <typename Height>
void add_floor(HMap& map, double x0, double x1, double y0, double y1, Height height) {
  for (auto i = static_cast<std::int32_t>(std::floor(x0 / kCell)); i < static_cast<std::int32_t>(std::floor(x1 / kCell)); ++i) {
    for (auto j = static_cast<std::int32_t>(std::floor(y0 / kCell)); j < static_cast<std::int32_t>(std::floor(y1 / kCell)); ++j) {
      const Eigen::Vector2d c = map.cell_center({i, j});
      const auto top = static_cast<float>(height(c.x(), c.y()));
      map.column_for_update({i, j}).push_back({top - 0.05F, top, 10.0F, 1.0F});
    }
  }
}

HMap empty_map() {
  Params p;
  p.map.cell_size = kCell;
  return HMap(p);
}

GroundParams params() {
  GroundParams g;
  g.iterations = 300;
  g.expansion_distance = 0.6;
  return g;
}

TEST(GroundTrackerTest, GrowsWithTheMapAndKeepsWhatItFound) {
  HMap map = empty_map();
  const auto flat = [](double, double) { return 0.0; };
  add_floor(map, -3.0, 3.0, -3.0, 3.0, flat);
  GroundTracker tracker(params());
  const GroundResult first = tracker.update(map, {0.0, 0.0, 1.0}, 10.0);
  EXPECT_TRUE(first.seeded);
  EXPECT_GT(first.accepted, 20);
  const std::size_t after_first = tracker.patches().size();
  for (const GroundPatch& p : tracker.patches()) {
    EXPECT_LE(std::abs(p.center.x()), 3.0 + tracker.window());  // a window may overhang the edge
    EXPECT_NEAR(p.center.z(), 0.0, 1e-6);
  }
  // The robot drives on: the floor now reaches x = 9 and the tree follows without a new root.
  add_floor(map, 3.0, 9.0, -3.0, 3.0, flat);
  for (int k = 0; k < 3; ++k) {
    const GroundResult more = tracker.update(map, {6.0, 0.0, 1.0}, 10.0);
    EXPECT_FALSE(more.seeded);
  }
  EXPECT_GT(tracker.patches().size(), after_first);
  double x_max = 0.0;
  for (const GroundPatch& p : tracker.patches()) x_max = std::max(x_max, p.center.x());
  EXPECT_GT(x_max, 7.5);
  // Patches are only appended: the first ones are unchanged and every parent comes earlier.
  for (std::size_t k = 0; k < tracker.patches().size(); ++k) EXPECT_LT(tracker.patches()[k].parent, static_cast<int>(k));
}

TEST(GroundTrackerTest, TenDegreeSlopeIsFollowed) {
  HMap map = empty_map();
  const double slope = std::tan(10.0 * M_PI / 180.0);
  add_floor(map, -4.0, 4.0, -2.0, 2.0, [&](double x, double) { return slope * x; });
  GroundParams g = params();
  g.elevation_threshold = 0.2;
  GroundTracker tracker(g);
  tracker.update(map, {0.0, 0.0, 1.0}, 6.0);
  ASSERT_GT(tracker.patches().size(), 10U);
  for (const GroundPatch& p : tracker.patches()) {
    EXPECT_NEAR(p.center.z(), slope * p.center.x(), 0.02);
    // Windows hanging over the floor's edge are partly IDW-filled from one side: judge the inner ones.
    if (std::abs(p.center.x()) > 4.0 - 2 * tracker.window() || std::abs(p.center.y()) > 2.0 - 2 * tracker.window()) continue;
    // The normal tilts by 10° about y: n = (−sin 10°, 0, cos 10°).
    EXPECT_NEAR(p.normal.x(), -std::sin(10.0 * M_PI / 180.0), 0.01);
    EXPECT_NEAR(p.normal.y(), 0.0, 0.01);
  }
  double x_min = 0.0;
  double x_max = 0.0;
  for (const GroundPatch& p : tracker.patches()) {
    x_min = std::min(x_min, p.center.x());
    x_max = std::max(x_max, p.center.x());
  }
  EXPECT_LT(x_min, -2.5);
  EXPECT_GT(x_max, 2.5);
}

TEST(GroundTrackerTest, StepAboveElevationThresholdSplitsThePatches) {
  HMap map = empty_map();
  // A 30 cm step at x = 0 with E_th = 0.2: the tree seeded on the low side stays there.
  add_floor(map, -4.0, 4.0, -2.0, 2.0, [](double x, double) { return x < 0.0 ? 0.0 : 0.3; });
  GroundParams g = params();
  g.elevation_threshold = 0.2;
  GroundTracker tracker(g);
  tracker.update(map, {-2.0, 0.0, 1.0}, 6.0);
  ASSERT_GT(tracker.patches().size(), 10U);
  for (const GroundPatch& p : tracker.patches()) {
    EXPECT_LT(p.center.x(), 0.35) << "a patch crossed the step";
    EXPECT_NEAR(p.center.z(), 0.0, 0.05);
  }
}

TEST(GroundTrackerTest, ContinuesASavedTreeAndIsReproducible) {
  HMap map = empty_map();
  add_floor(map, -3.0, 3.0, -3.0, 3.0, [](double, double) { return 0.0; });
  GroundTracker a(params());
  GroundTracker b(params());
  a.update(map, {0.0, 0.0, 1.0}, 5.0);
  b.update(map, {0.0, 0.0, 1.0}, 5.0);
  ASSERT_EQ(a.patches().size(), b.patches().size());
  for (std::size_t k = 0; k < a.patches().size(); ++k) EXPECT_EQ(a.patches()[k].center, b.patches()[k].center);
  GroundTracker resumed(params(), params().expansion_distance / 2.0, a.patches());
  EXPECT_EQ(resumed.patches().size(), a.patches().size());
  const GroundResult r = resumed.update(map, {0.0, 0.0, 1.0}, 5.0);
  EXPECT_FALSE(r.seeded);  // the saved tree is there: no new root
}

TEST(GroundTrackerTest, EmptyMapAndBadInput) {
  const HMap map = empty_map();
  GroundTracker tracker(params());
  const GroundResult r = tracker.update(map, {0.0, 0.0, 1.0}, 5.0);
  EXPECT_FALSE(r.seeded);
  EXPECT_TRUE(tracker.patches().empty());
  EXPECT_THROW(tracker.update(map, {std::nan(""), 0.0, 0.0}, 5.0), Error);
  EXPECT_THROW(tracker.update(map, {0.0, 0.0, 0.0}, 0.0), Error);
  EXPECT_THROW(tracker.update(map, {0.0, 0.0, 0.0}, std::numeric_limits<double>::infinity()), Error);
  GroundParams bad = params();
  bad.expansion_distance = -1.0;
  EXPECT_THROW(GroundTracker{bad}, Error);
}

TEST(GroundTrackerTest, LostGroundIsReseededUnderTheSensor) {
  // Two floors 14 m apart and 0.5 m apart in height, nothing between: the tree of the first
  // cannot grow onto the second. With a reach of 30 m the sensor over the second floor still has
  // patches of the first in reach; it is 8 d_n = 4.8 m from every patch, so the tracker re-seeds.
  HMap map = empty_map();
  add_floor(map, -3.0, 3.0, -3.0, 3.0, [](double, double) { return 0.0; });
  add_floor(map, 17.0, 23.0, -3.0, 3.0, [](double, double) { return 0.5; });
  GroundTracker tracker(params());
  ASSERT_TRUE(tracker.update(map, {0.0, 0.0, 1.0}, 30.0).seeded);
  for (const GroundPatch& p : tracker.patches()) ASSERT_LT(p.center.x(), 4.0);
  const GroundResult there = tracker.update(map, {20.0, 0.0, 1.5}, 30.0);
  EXPECT_TRUE(there.seeded);
  std::size_t on_second = 0;
  for (const GroundPatch& p : tracker.patches()) {
    if (p.center.x() > 16.0) {
      ++on_second;
      EXPECT_NEAR(p.center.z(), 0.5, 1e-6);
    }
  }
  EXPECT_GT(on_second, 10U);
  // Back at the first floor nothing is seeded again: patches lie under the sensor.
  EXPECT_FALSE(tracker.update(map, {0.0, 0.0, 1.0}, 30.0).seeded);
}

TEST(GroundTrackerTest, SeedsOnTheGroundNotOnTheCarBodyAtQuarterMetreCells) {
  // An HDL-64 on a car at 0.25 m cells (the outdoor default), sensor at z = 0: the ground at
  // -1.73 m is seen from 3.75 m on (the lowest beam, -24.8 deg), and three cells of the car's own
  // body at -0.54 m lie 1.6 m from the sensor. Seeding on the body gave one patch and nothing
  // connected to it; the root must be on the ground, and the tree must grow over it.
  Params p;
  p.map.cell_size = 0.25;
  HMap map(p);
  const auto at = [&](double x, double y) {
    return CellKey{static_cast<std::int32_t>(std::floor(x / 0.25)), static_cast<std::int32_t>(std::floor(y / 0.25))};
  };
  for (double x = -12.0; x < 12.0; x += 0.25) {
    for (double y = -12.0; y < 12.0; y += 0.25) {
      const Eigen::Vector2d c = map.cell_center(at(x + 0.1, y + 0.1));
      if (c.norm() < 3.75) continue;
      map.column_for_update(at(x + 0.1, y + 0.1)).push_back({-1.78F, -1.73F, 10.0F, 1.0F});
    }
  }
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(-1.125, 1.125), Eigen::Vector2d(-1.125, 0.875), Eigen::Vector2d(-0.875, 1.125)}) {
    map.column_for_update(at(xy.x(), xy.y())).push_back({-0.6F, -0.54F, 10.0F, 1.0F});
  }
  GroundTracker tracker(p.ground);
  const GroundResult r = tracker.update(map, {0.0, 0.0, 0.0}, 25.0);
  ASSERT_TRUE(r.seeded);
  EXPECT_NEAR(tracker.patches()[0].center.z(), -1.73, 0.01);
  EXPECT_GT(tracker.patches().size(), 50U);
  for (const GroundPatch& g : tracker.patches()) EXPECT_NEAR(g.center.z(), -1.73, 0.05);
}

}  // namespace ground_tracker_test
}  // namespace hmap
