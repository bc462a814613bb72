#include "hmap/maps/ray_trace.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <utility>
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

std::vector<Visit> walk_from(double x0, double y0, double x1, double y1, double cell, double t_start) {
  std::vector<Visit> out;
  traverse_2d_from(x0, y0, x1, y1, cell, t_start, [&](const CellKey& k, double a, double b) {
    out.push_back({k, a, b});
    return true;
  });
  return out;
}

/// Segments that hit grid corners exactly: cell centre to cell centre along slopes 1, 1/2, 2/3, 3/1,
/// axis-aligned ones, and a start on a grid line.
std::vector<std::array<double, 4>> corner_segments() {
  std::vector<std::array<double, 4>> out;
  for (const auto& [di, dj] : std::vector<std::pair<int, int>>{{4, 4}, {-4, 4}, {6, 3}, {-6, -3}, {6, 4}, {3, 9}, {5, 0}, {0, -7}, {0, 0}}) {
    out.push_back({0.5, 0.5, 0.5 + di, 0.5 + dj});
    out.push_back({2.0, 1.0, 2.0 + di, 1.0 + dj});  // starts on a corner
  }
  return out;
}

TEST(RayTraceFromTest, WholeWalkByHand) {
  // (0.5, 0.5) -> (2.5, 2.5) crosses the corners (1, 1) and (2, 2): at a tie j steps first.
  const auto v = walk_from(0.5, 0.5, 2.5, 2.5, 1.0, 0.0);
  const std::vector<CellKey> keys{{0, 0}, {0, 1}, {1, 1}, {1, 2}, {2, 2}};
  ASSERT_EQ(v.size(), keys.size());
  for (std::size_t k = 0; k < keys.size(); ++k) EXPECT_EQ(v[k].key, keys[k]) << k;
  EXPECT_DOUBLE_EQ(v[0].t_out, 0.25);
  EXPECT_DOUBLE_EQ(v[1].t_in, 0.25);
  EXPECT_DOUBLE_EQ(v[1].t_out, 0.25);  // touched at the corner only
  EXPECT_DOUBLE_EQ(v[4].t_in, 0.75);
  EXPECT_DOUBLE_EQ(v[4].t_out, 1.0);
  // From t = 0.5 on: the first cell whose t_out >= 0.5 is (1, 1) (it leaves at 0.75).
  const auto tail = walk_from(0.5, 0.5, 2.5, 2.5, 1.0, 0.5);
  ASSERT_EQ(tail.size(), 3U);
  EXPECT_EQ(tail[0].key, (CellKey{1, 1}));
  EXPECT_DOUBLE_EQ(tail[0].t_in, 0.25);
  EXPECT_TRUE(walk_from(0.5, 0.5, 2.5, 2.5, 1.0, 1.5).empty());
  ASSERT_EQ(walk_from(0.5, 0.5, 2.5, 2.5, 1.0, 1.0).size(), 1U);  // the end cell, t_out = 1
}

// Started anywhere, the walk is exactly (keys and t values, bit for bit) the tail of the whole walk
// from the first cell whose t_out >= t_start: on random segments and on segments through corners.
TEST(RayTraceFromTest, LateStartIsTheTailOfTheWholeWalk) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-30.0, 30.0);
  std::uniform_real_distribution<double> t01(-0.1, 1.05);
  auto segments = corner_segments();
  for (int trial = 0; trial < 2000; ++trial) segments.push_back({u(rng), u(rng), u(rng), u(rng)});
  for (const auto& [x0, y0, x1, y1] : segments) {
    for (const double cell : {1.0, 0.2, 0.25}) {
      const auto whole = walk_from(x0, y0, x1, y1, cell, 0.0);
      ASSERT_FALSE(whole.empty());
      std::vector<double> starts{0.0, 1.0};
      for (int k = 0; k < 8; ++k) starts.push_back(t01(rng));
      for (const Visit& v : whole) starts.push_back(v.t_out);  // exactly on a crossing
      for (const double t_start : starts) {
        const auto tail = walk_from(x0, y0, x1, y1, cell, t_start);
        std::size_t first = 0;
        while (first < whole.size() && whole[first].t_out < t_start) ++first;
        ASSERT_EQ(tail.size(), whole.size() - first) << x0 << " " << y0 << " " << x1 << " " << y1 << " t " << t_start;
        for (std::size_t k = 0; k < tail.size(); ++k) {
          ASSERT_EQ(tail[k].key, whole[first + k].key);
          ASSERT_EQ(tail[k].t_in, whole[first + k].t_in);
          ASSERT_EQ(tail[k].t_out, whole[first + k].t_out);
        }
      }
    }
  }
}

// The whole walk is traverse_2d's (so the sampling twin above holds for it too) on random segments,
// where no grid corner is hit. Through a corner, traverse_2d's accumulated sums break the tie by
// rounding, traverse_2d_from always steps j first (WholeWalkByHand); both walks are exact there.
TEST(RayTraceFromTest, WholeWalkIsTraverse2dAwayFromCorners) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-30.0, 30.0);
  std::vector<std::array<double, 4>> segments;
  for (int trial = 0; trial < 3000; ++trial) segments.push_back({u(rng), u(rng), u(rng), u(rng)});
  for (const auto& [x0, y0, x1, y1] : segments) {
    for (const double cell : {1.0, 0.2}) {
      const auto a = walk(x0, y0, x1, y1, cell);
      const auto b = walk_from(x0, y0, x1, y1, cell, 0.0);
      ASSERT_EQ(a.size(), b.size());
      for (std::size_t k = 0; k < a.size(); ++k) {
        ASSERT_EQ(a[k].key, b[k].key);
        EXPECT_NEAR(a[k].t_in, b[k].t_in, 1e-9);
        EXPECT_NEAR(a[k].t_out, b[k].t_out, 1e-9);
      }
    }
  }
}

// Through corners the walk is still exact: 4-connected, every sample's cell visited in order with
// its t inside the cell's [t_in, t_out].
TEST(RayTraceFromTest, CornerSegmentsMatchDenseSampling) {
  for (const auto& [x0, y0, x1, y1] : corner_segments()) {
    const auto v = walk_from(x0, y0, x1, y1, 1.0, 0.0);
    for (std::size_t k = 1; k < v.size(); ++k) {
      EXPECT_EQ(std::abs(v[k].key.i - v[k - 1].key.i) + std::abs(v[k].key.j - v[k - 1].key.j), 1);
      EXPECT_EQ(v[k].t_in, v[k - 1].t_out);
    }
    std::size_t cursor = 0;
    for (int s = 0; s <= 4000; ++s) {
      const double t = s / 4000.0;
      const CellKey key{static_cast<int>(std::floor(x0 + t * (x1 - x0))), static_cast<int>(std::floor(y0 + t * (y1 - y0)))};
      while (cursor < v.size() && !(v[cursor].key == key)) ++cursor;
      ASSERT_LT(cursor, v.size()) << x0 << " " << y0 << " " << x1 << " " << y1 << " sample " << s;
      EXPECT_GE(t, v[cursor].t_in - 1e-12);
      EXPECT_LE(t, v[cursor].t_out + 1e-12);
    }
  }
}

TEST(RayTraceFromTest, VisitorCanStop) {
  int n = 0;
  traverse_2d_from(0.5, 0.5, 10.5, 0.5, 1.0, 0.3, [&](const CellKey&, double, double) { return ++n < 2; });
  EXPECT_EQ(n, 2);
}

}  // namespace
}  // namespace hmap
