#include "hmap/maps/raycast.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

void put(HMap& m, CellKey key, float lo, float hi) {
  TileColumn c = m.column_for_update(key);
  c.push_back(HVoxel{lo, hi, 1.0F, 0.0F});
}

/// The brute-force twin: the ray against every HVoxel of the map as a box [i·s, (i+1)·s] ×
/// [j·s, (j+1)·s] × [z_min, z_max] by the slab method; the least entry range in [0, max_range].
std::optional<double> slab_twin(const HMap& map, const Eigen::Vector3d& o, const Eigen::Vector3d& dir, double max_range) {
  const Eigen::Vector3d d = dir.normalized();
  const double s = map.cell_size();
  std::optional<double> best;
  map.for_each_column([&](const CellKey& k, const ColumnView& c) {
    for (const HVoxel& v : c.hvoxels()) {
      const Eigen::Vector3d lo(k.i * s, k.j * s, v.z_min);
      const Eigen::Vector3d hi((k.i + 1) * s, (k.j + 1) * s, v.z_max);
      double t0 = -std::numeric_limits<double>::infinity();
      double t1 = std::numeric_limits<double>::infinity();
      bool miss = false;
      for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
          miss = miss || o[a] < lo[a] || o[a] > hi[a];
          continue;
        }
        const double ta = (lo[a] - o[a]) / d[a];
        const double tb = (hi[a] - o[a]) / d[a];
        t0 = std::max(t0, std::min(ta, tb));
        t1 = std::min(t1, std::max(ta, tb));
      }
      if (miss || t0 > t1 || t1 < 0.0) continue;
      const double t = std::max(t0, 0.0);
      if (t > max_range) continue;
      if (!best || t < *best) best = t;
    }
  });
  return best;
}

TEST(Raycast, HandComputedHitsAndMisses) {
  Params p;
  p.map.cell_size = 0.5;
  HMap map(p);
  put(map, {4, 0}, 0.0F, 2.0F);  // a post: x in [2, 2.5], y in [0, 0.5], z in [0, 2]
  put(map, {0, 0}, -1.0F, -0.8F);  // the floor under the origin's cell
  // Level along +x at z = 1 from (0.1, 0.2): enters the post's cell at x = 2.
  auto h = raycast(map, {0.1, 0.2, 1.0}, {1, 0, 0}, 10.0);
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->range, 1.9, 1e-12);
  EXPECT_EQ(h->cell, (CellKey{4, 0}));
  EXPECT_EQ(h->hvoxel.z_max, 2.0F);
  EXPECT_NEAR(h->point.x(), 2.0, 1e-12);
  // Over the post (z = 2.5): nothing; short of it (max 1.8 m): nothing.
  EXPECT_FALSE(raycast(map, {0.1, 0.2, 2.5}, {1, 0, 0}, 10.0));
  EXPECT_FALSE(raycast(map, {0.1, 0.2, 1.0}, {1, 0, 0}, 1.8));
  // Falling onto its top: from (2.25, 0.25, 3) straight down, 1 m to z = 2.
  h = raycast(map, {2.25, 0.25, 3.0}, {0, 0, -5}, 10.0);
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->range, 1.0, 1e-12);
  // Down and a little east from (0.1, 0.2, 0), direction (1, 0, -4): the floor cell's top z = -0.8
  // at x = 0.3, still in its cell, 0.8·√17 / 4 on. Shallower, (1, 0, -1), the ray leaves the cell
  // (x = 0.5) at z = -0.4, over the floor, and meets nothing.
  h = raycast(map, {0.1, 0.2, 0.0}, {1, 0, -4}, 10.0);
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->range, 0.2 * std::sqrt(17.0), 1e-7);  // -0.8 as a float
  EXPECT_NEAR(h->point.x(), 0.3, 1e-7);
  EXPECT_FALSE(raycast(map, {0.1, 0.2, 0.0}, {1, 0, -1}, 10.0));
  // Started inside the post: range 0.
  h = raycast(map, {2.2, 0.1, 1.0}, {-1, 0, 0}, 10.0);
  ASSERT_TRUE(h);
  EXPECT_EQ(h->range, 0.0);
  // Up the other way: nothing.
  EXPECT_FALSE(raycast(map, {0.1, 0.2, 1.0}, {-1, 0, 0}, 10.0));
  // An empty map: nothing, however far.
  EXPECT_FALSE(raycast(HMap(p), {0, 0, 0}, {1, 1, 0}, 1e6));
}

TEST(Raycast, EqualsTheSlabTwinOnRandomMapsAndRays) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Params p;
  p.map.cell_size = 0.2;
  HMap map(p);
  // 300 columns in a 6 m square, one to three HVoxels each (some flat: z_min = z_max).
  for (int c = 0; c < 300; ++c) {
    const CellKey k{static_cast<int>(std::floor(15.0 * u(rng))), static_cast<int>(std::floor(15.0 * u(rng)))};
    if (!map.column(k).empty()) continue;
    float z = static_cast<float>(2.0 * u(rng) - 1.0);
    const int n = 1 + static_cast<int>(3.0 * (0.5 + 0.5 * u(rng))) % 3;
    for (int q = 0; q < n; ++q) {
      const float h = q == 1 ? 0.0F : static_cast<float>(0.3 * (1.0 + u(rng)));
      put(map, k, z, z + h);
      z += h + 0.2F + static_cast<float>(0.3 * (1.0 + u(rng)));
    }
  }
  int hits = 0;
  for (int r = 0; r < 4000; ++r) {
    const Eigen::Vector3d o(4.0 * u(rng), 4.0 * u(rng), 2.0 * u(rng));
    Eigen::Vector3d d(u(rng), u(rng), 0.5 * u(rng));
    if (r % 10 == 0) d.z() = 0.0;  // level rays too
    const double max_range = 1.0 + 8.0 * (0.5 + 0.5 * u(rng));
    const auto got = raycast(map, o, d, max_range);
    const auto want = slab_twin(map, o, d, max_range);
    ASSERT_EQ(got.has_value(), want.has_value()) << r;
    if (got) {
      ++hits;
      EXPECT_NEAR(got->range, *want, 1e-9) << r;
      EXPECT_TRUE(map.occupied(got->point.x(), got->point.y(), got->point.z()) ||
                  std::abs(got->point.x() / 0.2 - std::round(got->point.x() / 0.2)) < 1e-9 ||
                  std::abs(got->point.y() / 0.2 - std::round(got->point.y() / 0.2)) < 1e-9)
          << r;  // on a border the point may fall in the neighbour's cell
    }
  }
  EXPECT_GT(hits, 500);  // the rays do meet the map, and miss it too (998 of 4000 with this seed)
  EXPECT_LT(hits, 3900);
}

TEST(Raycast, RefusesBadRays) {
  Params p;
  HMap map(p);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)raycast(map, {nan, 0, 0}, {1, 0, 0}, 1.0), Error);
  EXPECT_THROW((void)raycast(map, {0, 0, 0}, {0, 0, 0}, 1.0), Error);
  EXPECT_THROW((void)raycast(map, {0, 0, 0}, {1, nan, 0}, 1.0), Error);
  EXPECT_THROW((void)raycast(map, {0, 0, 0}, {1, 0, 0}, -1.0), Error);
  EXPECT_THROW((void)raycast(map, {0, 0, 0}, {1, 0, 0}, 2e6), Error);
  EXPECT_THROW((void)raycast(map, {1e12, 0, 0}, {1, 0, 0}, 1.0), Error);
}

}  // namespace
}  // namespace hmap
