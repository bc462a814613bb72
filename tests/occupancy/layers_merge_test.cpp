#include "hmap/occupancy/layers_merge.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

TEST(LayersMerge, EvidenceAddsClampsAndUnknownTakesTheOther) {
  OccupancyGrid a(0.25, 0.12, 0.97), b(0.25, 0.12, 0.97);
  a.set({0, 0}, 0.8F);
  a.set({1, 0}, 3.0F);
  b.set({0, 0}, -0.5F);
  b.set({1, 0}, 3.0F);   // 6.0 clamps to log(0.97 / 0.03) = 3.476
  b.set({-4, 9}, -1.0F);  // unknown in a
  add_evidence(a, b);
  EXPECT_NEAR(*a.log_odds_at({0, 0}), 0.3F, 1e-6);
  EXPECT_NEAR(*a.log_odds_at({1, 0}), std::log(0.97 / 0.03), 1e-5);
  EXPECT_NEAR(*a.log_odds_at({-4, 9}), -1.0F, 1e-7);
  EXPECT_EQ(a.known_cells(), 3U);
  OccupancyGrid other(0.2, 0.12, 0.97);
  EXPECT_THROW(add_evidence(a, other), Error);
}

TEST(LayersMerge, GridQuarterTurnMovesEveryCell) {
  OccupancyGrid g(0.5, 0.12, 0.97);
  for (int i = -5; i < 7; ++i) g.set({i, 2 * i + 1}, static_cast<float>(i) * 0.1F);
  const OccupancyGrid t = shifted_grid(g, {1.0, 0.0, 0.0, std::numbers::pi / 2});
  EXPECT_EQ(t.known_cells(), g.known_cells());
  // (i + ½, j + ½)·0.5 turned by 90° then 1 m (2 cells) along x: cell (−j − 1 + 2, i).
  for (int i = -5; i < 7; ++i) EXPECT_NEAR(*t.log_odds_at({-(2 * i + 1) - 1 + 2, i}), static_cast<float>(i) * 0.1F, 1e-7) << i;
  EXPECT_THROW((void)shifted_grid(g, {INFINITY, 0.0, 0.0, 0.0}), Error);
}

GroundPatch patch(double x, double y, int parent, double half = 0.5) {
  return {Eigen::Vector3d(x, y, 0.0), Eigen::Vector3d::UnitZ(), half, parent};
}

TEST(LayersMerge, GroundJoinsOutsideTheFirstsPatchesAndKeepsATree) {
  std::vector<GroundPatch> a{patch(0, 0, -1), patch(1, 0, 0)};
  // b: a root under a's first patch (dropped), its child beyond (kept, now a root), that one's
  // child (kept, parent remapped), and a patch under a's second (dropped).
  const std::vector<GroundPatch> b{patch(0.3, 0.2, -1), patch(3, 0, 0), patch(4, 0, 1), patch(1.4, -0.4, 2)};
  EXPECT_EQ(join_ground(a, b), 2U);
  ASSERT_EQ(a.size(), 4U);
  EXPECT_EQ(a[2].center.x(), 3.0);
  EXPECT_EQ(a[2].parent, -1);
  EXPECT_EQ(a[3].center.x(), 4.0);
  EXPECT_EQ(a[3].parent, 2);
  std::vector<GroundPatch> empty;
  EXPECT_EQ(join_ground(empty, b), 4U);
  EXPECT_EQ(empty[1].parent, 0);
}

TEST(LayersMerge, GroundShiftTurnsCentresAndNormals) {
  GroundPatch p = patch(1, 0, -1);
  p.normal = Eigen::Vector3d(0.1, 0.0, 1.0).normalized();
  const auto moved = shifted_ground(std::vector<GroundPatch>{p}, {0.0, 2.0, 0.5, std::numbers::pi / 2});
  EXPECT_NEAR(moved[0].center.x(), 0.0, 1e-12);
  EXPECT_NEAR(moved[0].center.y(), 3.0, 1e-12);
  EXPECT_NEAR(moved[0].center.z(), 0.5, 1e-12);
  EXPECT_NEAR(moved[0].normal.y(), p.normal.x(), 1e-12);
  EXPECT_NEAR(moved[0].normal.z(), p.normal.z(), 1e-12);
}

}  // namespace
}  // namespace hmap
