#include "hmap/baseline/elevation_mapper.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

Params params() {
  Params p;
  p.map.cell_size = 0.25;
  p.map.min_range = 0.5;
  p.map.max_range = 10.0;
  return p;
}

/// σ = 0.05 + 0.05·r: 0.1 m at 1 m, 0.2 m at 3 m.
ElevationParams noise() {
  ElevationParams e;
  e.sigma_base = 0.05;
  e.sigma_per_metre = 0.05;
  return e;
}

Pose at(double x, double y, double z) {
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

ElevationCell known(float h, float variance) { return {h, variance, h, 1}; }

TEST(ElevationFusionTest, TwoMeasurementsGiveTheTextbookPosterior) {
  const ElevationParams e = noise();
  ElevationCell c;
  EXPECT_EQ(fuse_measurement(c, 1.0, 0.01, e), ElevationFusion::kInitialized);
  c.points = 1;
  EXPECT_FLOAT_EQ(c.elevation, 1.0F);
  EXPECT_FLOAT_EQ(c.variance, 0.01F);
  // h = (0.04·1.0 + 0.01·1.1) / 0.05 = 1.02, σ² = 0.01·0.04 / 0.05 = 0.008.
  EXPECT_EQ(fuse_measurement(c, 1.1, 0.04, e), ElevationFusion::kFused);
  EXPECT_NEAR(c.elevation, 1.02, 1e-6);
  EXPECT_NEAR(c.variance, 0.008, 1e-8);
  // Equal variances: the mean, half the variance.
  ElevationCell d = known(0.0F, 0.25F);
  EXPECT_EQ(fuse_measurement(d, 0.5, 0.25, e), ElevationFusion::kFused);
  EXPECT_FLOAT_EQ(d.elevation, 0.25F);
  EXPECT_FLOAT_EQ(d.variance, 0.125F);
}

// σ_h² = σ_z² = 0.125, threshold 2: the gate is 2·sqrt(0.25) = 1 m exactly.
TEST(ElevationFusionTest, HigherReplacesBeyondTheGateOnly) {
  ElevationParams e = noise();
  e.mahalanobis_threshold = 2.0;
  e.multi_height_noise = 0.001;
  ElevationCell at_gate = known(1.0F, 0.125F);
  EXPECT_EQ(fuse_measurement(at_gate, 2.0, 0.125, e), ElevationFusion::kFused);  // d = gate: fused
  EXPECT_FLOAT_EQ(at_gate.elevation, 1.5F);
  ElevationCell above = known(1.0F, 0.125F);
  EXPECT_EQ(fuse_measurement(above, 2.0 + 1e-6, 0.125, e), ElevationFusion::kReplaced);
  EXPECT_FLOAT_EQ(above.elevation, static_cast<float>(2.0 + 1e-6));
  EXPECT_FLOAT_EQ(above.variance, 0.125F);
  ElevationCell low_gate = known(1.0F, 0.125F);
  EXPECT_EQ(fuse_measurement(low_gate, 0.0, 0.125, e), ElevationFusion::kFused);
  EXPECT_FLOAT_EQ(low_gate.elevation, 0.5F);
  ElevationCell below = known(1.0F, 0.125F);
  EXPECT_EQ(fuse_measurement(below, -1e-6, 0.125, e), ElevationFusion::kRejectedLower);
  EXPECT_FLOAT_EQ(below.elevation, 1.0F);  // the higher surface stays
  EXPECT_FLOAT_EQ(below.variance, 0.126F);  // with more doubt
}

TEST(ElevationFusionTest, RangeDependentNoise) {
  const ElevationParams e = noise();
  EXPECT_NEAR(measurement_variance(1.0, e), 0.01, 1e-15);
  EXPECT_NEAR(measurement_variance(3.0, e), 0.04, 1e-15);
  EXPECT_NEAR(measurement_variance(0.0, e), 0.0025, 1e-15);
}

// The same posterior through the mapper: ranges 1 m and 3 m straight up, in cell (2, 0).
TEST(ElevationMapperTest, FusesScansWithRangeNoise) {
  ElevationMapper mapper(params(), noise());
  const PointCloud scan1{{0.0F, 0.0F, 1.0F}};
  const auto s1 = mapper.integrate(scan1, at(0.6, 0.1, 0.0));
  EXPECT_EQ(s1.initialized, 1U);
  const PointCloud scan2{{0.0F, 0.0F, 3.0F}};
  const auto s2 = mapper.integrate(scan2, at(0.6, 0.1, -1.9));
  EXPECT_EQ(s2.fused, 1U);
  const ElevationCell* c = mapper.map().find(CellKey{2, 0});
  ASSERT_NE(c, nullptr);
  EXPECT_NEAR(c->elevation, 1.02, 1e-6);
  EXPECT_NEAR(c->variance, 0.008, 1e-8);
  EXPECT_NEAR(c->lowest, 1.0, 1e-6);
  EXPECT_EQ(c->points, 2U);
  EXPECT_EQ(mapper.map().known_cells(), 1U);
}

// Per scan a cell's measurement is its highest point, with the variance of that point's range.
TEST(ElevationMapperTest, HighestPointOfTheScanPerCell) {
  ElevationMapper mapper(params(), noise());
  // Sensor at (0.6, 0.1, 0); cell (2, 0) is x in [0.5, 0.75), y in [0, 0.25).
  const PointCloud scan{{0.0F, 0.0F, -1.0F}, {0.1F, 0.1F, 3.0F}, {-0.05F, 0.0F, 2.0F}, {1.0F, 0.0F, 0.0F}};
  const auto s = mapper.integrate(scan, at(0.6, 0.1, 0.0));
  EXPECT_EQ(s.points_kept, 4U);
  EXPECT_EQ(s.cells, 2U);
  EXPECT_EQ(s.initialized, 2U);
  const ElevationCell* c = mapper.map().find(CellKey{2, 0});
  ASSERT_NE(c, nullptr);
  EXPECT_FLOAT_EQ(c->elevation, 3.0F);
  EXPECT_FLOAT_EQ(c->lowest, -1.0F);
  EXPECT_EQ(c->points, 3U);
  const double r = std::sqrt(0.01 + 0.01 + 9.0);
  EXPECT_NEAR(c->variance, measurement_variance(r, noise()), 1e-7);
  EXPECT_DOUBLE_EQ(*mapper.map().elevation_at(1.6, 0.1), 0.0F);  // the other cell
}

TEST(ElevationMapperTest, DropsAreCounted) {
  ElevationParams e = noise();
  e.max_height_above_sensor = 1.5;
  ElevationMapper mapper(params(), e);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const PointCloud scan{{nan, 0.0F, 0.0F}, {1.0F, inf, 0.0F}, {0.0F, 0.0F, -inf},  // non-finite
                        {0.3F, 0.0F, 0.0F}, {11.0F, 0.0F, 0.0F},                     // too near, too far
                        {2.0F, 0.0F, 1.6F},                                          // above the limit
                        {2.0F, 0.0F, 1.4F}, {-3.0F, 2.0F, -1.0F}};                   // kept
  const auto s = mapper.integrate(scan, at(0.0, 0.0, 0.0));
  EXPECT_EQ(s.points_in, 8U);
  EXPECT_EQ(s.dropped_non_finite, 3U);
  EXPECT_EQ(s.dropped_range, 2U);
  EXPECT_EQ(s.dropped_height, 1U);
  EXPECT_EQ(s.points_kept, 2U);
  EXPECT_EQ(mapper.map().known_cells(), 2U);
  EXPECT_DOUBLE_EQ(*mapper.map().elevation_at(2.0, 0.0), 1.4F);
}

TEST(ElevationMapperTest, EmptyScan) {
  ElevationMapper mapper(params(), noise());
  const auto s = mapper.integrate(PointCloud{}, at(1.0, 2.0, 3.0));
  EXPECT_EQ(s.points_in, 0U);
  EXPECT_EQ(s.points_kept, 0U);
  EXPECT_EQ(s.cells, 0U);
  EXPECT_TRUE(mapper.map().empty());
  EXPECT_EQ(mapper.map().memory_bytes(), 0U);
}

TEST(ElevationMapperTest, UnboundedFarFromTheOrigin) {
  ElevationMapper mapper(params(), noise());
  const PointCloud scan{{1.0F, 0.0F, -0.5F}, {0.0F, -2.0F, 0.25F}};
  mapper.integrate(scan, at(1e5, -1e5, 0.0));
  mapper.integrate(scan, at(-1e5, 1e5, 0.0));
  EXPECT_EQ(mapper.map().known_cells(), 4U);
  EXPECT_EQ(mapper.map().tiles(), 4U);
  EXPECT_DOUBLE_EQ(*mapper.map().elevation_at(1e5 + 1.0, -1e5), -0.5F);
  EXPECT_DOUBLE_EQ(*mapper.map().elevation_at(-1e5, 1e5 - 2.0), 0.25F);
  EXPECT_EQ(*mapper.map().key_of(1e5 + 1.0, -1e5), (CellKey{400004, -400000}));
  EXPECT_FALSE(mapper.map().elevation_at(0.0, 0.0));
}

TEST(ElevationMapperTest, RejectsBadPosesAndParameters) {
  ElevationMapper mapper(params(), noise());
  const PointCloud scan{{1.0F, 0.0F, 0.0F}};
  EXPECT_THROW(mapper.integrate(scan, at(std::nan(""), 0.0, 0.0)), Error);
  EXPECT_THROW(mapper.integrate(scan, at(1e12, 0.0, 0.0)), Error);
  EXPECT_TRUE(mapper.map().empty());
  ElevationParams bad = noise();
  bad.sigma_base = 0.0;
  EXPECT_THROW(ElevationMapper(params(), bad), Error);
  bad = noise();
  bad.mahalanobis_threshold = -1.0;
  EXPECT_THROW(ElevationMapper(params(), bad), Error);
  bad = noise();
  bad.max_height_above_sensor = std::nan("");
  EXPECT_THROW(ElevationMapper(params(), bad), Error);
}

// A second identical scan fuses everywhere; a later, far higher one replaces.
TEST(ElevationMapperTest, ReplacedAcrossScans) {
  ElevationMapper mapper(params(), noise());
  const PointCloud floor{{2.0F, 0.0F, -1.0F}};
  const PointCloud top{{2.0F, 0.0F, 0.5F}};
  mapper.integrate(floor, at(0.0, 0.0, 0.0));
  EXPECT_EQ(mapper.integrate(floor, at(0.0, 0.0, 0.0)).fused, 1U);
  EXPECT_EQ(mapper.integrate(top, at(0.0, 0.0, 0.0)).replaced, 1U);
  EXPECT_DOUBLE_EQ(*mapper.map().elevation_at(2.0, 0.0), 0.5F);
  EXPECT_EQ(mapper.integrate(floor, at(0.0, 0.0, 0.0)).rejected_lower, 1U);
  const ElevationCell* c = mapper.map().find(2.0, 0.0);
  EXPECT_FLOAT_EQ(c->elevation, 0.5F);
  EXPECT_FLOAT_EQ(c->lowest, -1.0F);
  EXPECT_EQ(c->points, 4U);
}

}  // namespace
}  // namespace hmap
