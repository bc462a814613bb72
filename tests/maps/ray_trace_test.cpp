#include "hmap/maps/ray_trace.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace hmap {
namespace {

struct Visit {
  CellKey key;
  double t_in;
  double t_out;
};

std::vector<Visit> walk(double x0, double y0, double x1, double y1, double cell) {
  std::vector<Visit> out;
  traverse_2d(x0, y0, x1, y1, cell, [&](const CellKey& k, double a, double b) {
    out.push_back({k, a, b});
    return true;
  });
  return out;
}

TEST(RayTraceTest, SameCellIsOneVisit) {
  const auto v = walk(0.1, 0.1, 0.2, 0.3, 1.0);
  ASSERT_EQ(v.size(), 1U);
  EXPECT_EQ(v[0].key, (CellKey{0, 0}));
  EXPECT_DOUBLE_EQ(v[0].t_in, 0.0);
  EXPECT_DOUBLE_EQ(v[0].t_out, 1.0);
}

TEST(RayTraceTest, AxisAlignedByHand) {
  const auto v = walk(0.5, 0.5, 3.5, 0.5, 1.0);
  ASSERT_EQ(v.size(), 4U);
  for (int k = 0; k < 4; ++k) EXPECT_EQ(v[k].key, (CellKey{k, 0}));
  EXPECT_NEAR(v[0].t_out, 1.0 / 6.0, 1e-12);
  EXPECT_NEAR(v[1].t_out, 0.5, 1e-12);
  EXPECT_NEAR(v[2].t_out, 5.0 / 6.0, 1e-12);
}

TEST(RayTraceTest, NegativeDirectionAndNegativeKeys) {
  const auto v = walk(0.5, 0.5, -1.5, -0.5, 1.0);
  ASSERT_FALSE(v.empty());
  EXPECT_EQ(v.front().key, (CellKey{0, 0}));
  EXPECT_EQ(v.back().key, (CellKey{-2, -1}));
}

TEST(RayTraceTest, VisitorCanStop) {
  int n = 0;
  traverse_2d(0.5, 0.5, 10.5, 0.5, 1.0, [&](const CellKey&, double, double) { return ++n < 3; });
  EXPECT_EQ(n, 3);
}

// Brute-force twin: sample the segment finely; every sample's cell must be visited, with its t
// inside that cell's [t_in, t_out], and the visits must be 4-connected and in order.
TEST(RayTraceTest, MatchesDenseSampling) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  for (int trial = 0; trial < 300; ++trial) {
    const double cell = trial % 2 == 0 ? 0.25 : 0.2;
    const double x0 = u(rng), y0 = u(rng), x1 = u(rng), y1 = u(rng);
    const auto v = walk(x0, y0, x1, y1, cell);
    ASSERT_FALSE(v.empty());
    EXPECT_EQ(v.back().key,
              (CellKey{static_cast<int>(std::floor(x1 / cell)), static_cast<int>(std::floor(y1 / cell))}));
    for (std::size_t k = 1; k < v.size(); ++k) {
      const int manhattan = std::abs(v[k].key.i - v[k - 1].key.i) + std::abs(v[k].key.j - v[k - 1].key.j);
      EXPECT_EQ(manhattan, 1);
      EXPECT_NEAR(v[k].t_in, v[k - 1].t_out, 1e-12);
    }
    const int samples = 20000;
    std::size_t cursor = 0;
    for (int s = 0; s <= samples; ++s) {
      const double t = static_cast<double>(s) / samples;
      const CellKey key{static_cast<int>(std::floor((x0 + t * (x1 - x0)) / cell)),
                        static_cast<int>(std::floor((y0 + t * (y1 - y0)) / cell))};
      // Advance to the visit holding this sample (samples on a grid line may sit in either cell).
      while (cursor < v.size() && !(v[cursor].key == key)) ++cursor;
      ASSERT_LT(cursor, v.size()) << "trial " << trial << " sample " << s << " cell " << key.i << "," << key.j;
      EXPECT_GE(t, v[cursor].t_in - 1e-9);
      EXPECT_LE(t, v[cursor].t_out + 1e-9);
    }
  }
}

}  // namespace
}  // namespace hmap
