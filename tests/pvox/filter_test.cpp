#include "hmap/pvox/filter.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "hmap/core/error.hpp"

namespace hmap::pvox {
namespace {

TEST(Filter, FuseIsTheProductOfTwoGaussians) {
  // eq. (8)–(9) by hand: σ1² = 2000, σ2² = 100 (mm²), μ1 = 0, z = 21 mm.
  const AxisBelief post = fuse({0.0, 2000.0}, 21.0, 100.0);
  EXPECT_DOUBLE_EQ(post.variance, 2000.0 * 100.0 / 2100.0);
  EXPECT_DOUBLE_EQ(post.mean, (100.0 * 0.0 + 2000.0 * 21.0) / 2100.0);
  EXPECT_LT(post.variance, 100.0);  // smaller than both
}

TEST(Filter, PredictAddsMeansAndVariances) {
  const AxisBelief b = predict({1.0, 3.0}, 0.5, 2.0);
  EXPECT_DOUBLE_EQ(b.mean, 1.5);
  EXPECT_DOUBLE_EQ(b.variance, 5.0);
}

TEST(Filter, RecursivePosteriorVarianceConvergesToTheSeedsValue) {
  FilterParams p;  // 2000 mm² motion, 100 mm² measurement, as the seed
  PlanarFilter f(p, Eigen::Vector2d::Zero());
  f.update(Eigen::Vector2d::Zero());
  EXPECT_NEAR(f.variance().x() * 1e6, 2000.0 * 100.0 / 2100.0, 1e-9);
  for (int k = 0; k < 10; ++k) {
    const double prior = f.variance().x() + p.motion_variance;
    f.predict(Eigen::Vector2d(1.0, 0.0));
    EXPECT_NEAR(f.variance().x(), prior, 1e-15);
    f.update(f.mean());
    EXPECT_NEAR(f.variance().x(), prior * p.measurement_variance / (prior + p.measurement_variance), 1e-15);
  }
  // The fixed point of σ² = (σ² + q) r / (σ² + q + r): σ² = (−q + √(q² + 4 q r)) / 2 = 95.4451 mm²,
  // the seed's "95.4451 mm²", and 6σ is its 58.61 mm voxel.
  const double q = 2000.0;
  const double r = 100.0;
  const double fixed = (-q + std::sqrt(q * q + 4.0 * q * r)) / 2.0;
  EXPECT_NEAR(fixed, 95.4451, 1e-4);
  EXPECT_NEAR(f.variance().x() * 1e6, fixed, 1e-6);
  EXPECT_NEAR(f.variance().y() * 1e6, fixed, 1e-6);
  EXPECT_NEAR(6.0 * f.sigma() * 1000.0, 58.62, 0.01);
}

TEST(Filter, NaiveKeepsTheFirstVarianceAndIgnoresLaterMeasurements) {
  FilterParams p;
  p.kind = FilterKind::kNaive;
  PlanarFilter f(p, Eigen::Vector2d(1.0, 2.0));
  EXPECT_TRUE(f.wants_measurement());
  f.update(Eigen::Vector2d(1.0, 2.0));
  const Eigen::Vector2d first = f.variance();
  EXPECT_FALSE(f.wants_measurement());
  f.predict(Eigen::Vector2d(1.0, 0.0));
  f.update(Eigen::Vector2d(5.0, 5.0));  // ignored
  EXPECT_EQ(f.variance(), first);
  EXPECT_NEAR(f.mean().x(), 2.0, 1e-12);
  EXPECT_NEAR(f.mean().y(), 2.0, 1e-12);
}

TEST(Filter, RejectsBadVariances) {
  FilterParams p;
  p.measurement_variance = 0.0;
  EXPECT_THROW(PlanarFilter(p, Eigen::Vector2d::Zero()), Error);
  p.measurement_variance = NAN;
  EXPECT_THROW(PlanarFilter(p, Eigen::Vector2d::Zero()), Error);
}

}  // namespace
}  // namespace hmap::pvox
