#include "hmap/maps/extrusion.hpp"

#include <gtest/gtest.h>

namespace hmap {
namespace extrusion_test {

MapParams params() {
  MapParams p;
  p.cell_size = 0.25;
  p.min_hvoxel_height = 0.25;
  p.density_threshold = 0.5;
  return p;
}

HVoxel hv(float lo, float hi, float count) {
  HVoxel v{lo, hi, count, 0.0F};
  update_density(v, params());
  return v;
}

Column column_of(std::initializer_list<HVoxel> vs) {
  Column c;
  for (const auto& v : vs) c.push_back(v);
  return c;
}

float free_density(const FreeHVoxel& f) { return hvoxel_density(f.rays, f.z_max - f.z_min, params()); }

TEST(ExtrusionTest, RuleOneNoOverlapNoChange) {
  Column c = column_of({hv(0.0F, 1.0F, 500)});
  const Column before = c;
  ExtrusionCounts n;
  const FreeHVoxel f{1.5F, 2.5F, 1000};
  extrude(c, {&f, 1}, params(), n);
  ASSERT_EQ(c.size(), 1U);
  EXPECT_EQ(c[0], before[0]);
  EXPECT_EQ(n.updated + n.trimmed + n.subdivided + n.removed, 0U);
}

TEST(ExtrusionTest, RuleTwoWeakerFreeLowersCount) {
  // Occupied [0, 2] with 1000 points is dense; free [1.5, 3] with 5 rays is weaker.
  Column c = column_of({hv(0.0F, 2.0F, 1000)});
  const FreeHVoxel f{1.5F, 3.0F, 5};
  ASSERT_LT(free_density(f), c[0].density);
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  ASSERT_EQ(c.size(), 1U);
  // d = 0.5 / 2 = 0.25 of its height: |v| = 1000 - 0.25 * 5.
  EXPECT_FLOAT_EQ(c[0].count, 1000.0F - 0.25F * 5.0F);
  EXPECT_FLOAT_EQ(c[0].z_max, 2.0F);
  EXPECT_EQ(n.updated, 1U);
  EXPECT_EQ(n.trimmed, 0U);
}

TEST(ExtrusionTest, RuleTwoBelowThresholdRemovesOverlappedPart) {
  // 60 points over [0, 2]: ρ = σ(0.0005·55/0.125) ≈ 0.55; 10 rays over [1, 3] weigh ≈ 0.51.
  Column c = column_of({hv(0.0F, 2.0F, 60)});
  const FreeHVoxel f{1.0F, 3.0F, 10};
  ASSERT_LT(free_density(f), c[0].density);
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  // 60 − 0.5·10 = 55 gives ρ = σ(0.0005·50/0.125) ≈ 0.5498 >= 0.5: no trimming yet.
  ASSERT_EQ(c.size(), 1U);
  EXPECT_FLOAT_EQ(c[0].count, 55.0F);
  // Many weaker passes: each lowers the count until ρ < 0.5, then the top half goes.
  for (int k = 0; k < 20 && c.size() == 1 && c[0].z_max > 1.0F; ++k) extrude(c, {&f, 1}, params(), n);
  if (!c.empty()) {
    EXPECT_FLOAT_EQ(c[0].z_max, 1.0F);
  }
  EXPECT_GE(n.trimmed + n.removed, 1U);
}

TEST(ExtrusionTest, RuleThreeStrongerFreeRemovesOverlap) {
  Column c = column_of({hv(0.0F, 2.0F, 60)});
  const FreeHVoxel f{1.5F, 3.0F, 5000};
  ASSERT_GE(free_density(f), c[0].density);
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  ASSERT_EQ(c.size(), 1U);
  EXPECT_FLOAT_EQ(c[0].z_min, 0.0F);
  EXPECT_FLOAT_EQ(c[0].z_max, 1.5F);
  EXPECT_FLOAT_EQ(c[0].count, 45.0F);  // the kept 3/4 of the height keeps 3/4 of the points
  EXPECT_EQ(n.trimmed, 1U);
}

TEST(ExtrusionTest, RuleThreeFromBelowKeepsTop) {
  Column c = column_of({hv(1.0F, 3.0F, 400)});
  const FreeHVoxel f{0.0F, 2.0F, 50000};
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  ASSERT_EQ(c.size(), 1U);
  EXPECT_FLOAT_EQ(c[0].z_min, 2.0F);
  EXPECT_FLOAT_EQ(c[0].z_max, 3.0F);
}

TEST(ExtrusionTest, RuleThreeWhollyCoveredIsRemoved) {
  Column c = column_of({hv(1.0F, 1.2F, 8), hv(5.0F, 6.0F, 100)});
  const FreeHVoxel f{0.5F, 2.0F, 5000};
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  ASSERT_EQ(c.size(), 1U);
  EXPECT_FLOAT_EQ(c[0].z_min, 5.0F);
  EXPECT_EQ(n.removed, 1U);
}

TEST(ExtrusionTest, RuleFourWeakerFreeInsideSubdivides) {
  Column c = column_of({hv(0.0F, 3.0F, 3000)});
  const FreeHVoxel f{1.0F, 2.0F, 5};
  ASSERT_LT(free_density(f), c[0].density);
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  ASSERT_EQ(c.size(), 2U);
  EXPECT_FLOAT_EQ(c[0].z_min, 0.0F);
  EXPECT_FLOAT_EQ(c[0].z_max, 1.0F);
  EXPECT_FLOAT_EQ(c[1].z_min, 2.0F);
  EXPECT_FLOAT_EQ(c[1].z_max, 3.0F);
  EXPECT_FLOAT_EQ(c[0].count + c[1].count, 2000.0F);
  EXPECT_EQ(n.subdivided, 1U);
  EXPECT_TRUE(c.is_valid());
}

TEST(ExtrusionTest, RuleFourStrongerFreeInsideUpdates) {
  Column c = column_of({hv(0.0F, 3.0F, 80)});
  const FreeHVoxel f{1.0F, 2.0F, 400};
  ASSERT_GE(free_density(f), c[0].density);
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  // |v| = 80 − (1/3)·400 < 0 -> 0: ρ under n_th, so the final removal takes it.
  EXPECT_TRUE(c.empty());
  EXPECT_EQ(n.updated, 1U);
  EXPECT_EQ(n.removed, 1U);
}

TEST(ExtrusionTest, FinalRemovalSparesHVoxelsTheFreeSpaceDidNotReach) {
  Column c = column_of({hv(0.0F, 0.1F, 2), hv(2.0F, 2.1F, 2)});  // both under n_th
  const FreeHVoxel f{1.0F, 1.5F, 10};
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  EXPECT_EQ(c.size(), 2U);
}

TEST(ExtrusionTest, PointLikeHVoxelInsideFreeIsReached) {
  Column c = column_of({hv(1.0F, 1.0F, 1)});
  const FreeHVoxel f{0.5F, 1.5F, 3};
  ExtrusionCounts n;
  extrude(c, {&f, 1}, params(), n);
  EXPECT_TRUE(c.empty());
}

}  // namespace extrusion_test
}  // namespace hmap
