#include "hmap/maps/map_merge.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "hmap/core/error.hpp"
#include "hmap/maps/map_rebuild.hpp"
#include "hmap/maps/mapper.hpp"
#include "common/same_map.hpp"

namespace hmap {
namespace map_merge_test {

Params params(double cell = 0.25) {
  Params p = outdoor_preset();
  p.map.cell_size = cell;
  return p;
}

HVoxel hv(float lo, float hi, float count, const MapParams& p) {
  HVoxel v{lo, hi, count, 0.0F};
  update_density(v, p);
  return v;
}

void put(HMap& m, CellKey key, std::initializer_list<HVoxel> vs) {
  TileColumn c = m.column_for_update(key);
  for (const HVoxel& v : vs) c.push_back(v);
}

/// Every column of `a` equals `b`'s at the same cell, and both hold as many.
void expect_same(const HMap& a, const HMap& b) { test::expect_same_columns(a, b); }

/// A random map: `cells` columns in a square of `side` cells, 1-3 disjoint HVoxels each.
HMap random_map(const Params& p, int cells, int side, std::uint32_t seed) {
  HMap m(p);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> cell(-side / 2, side / 2);
  std::uniform_int_distribution<int> layers(1, 3);
  for (int k = 0; k < cells; ++k) {
    const CellKey key{cell(rng), cell(rng)};
    if (!m.column(key).empty()) continue;
    TileColumn c = m.column_for_update(key);
    float z = -1.0F + 0.1F * static_cast<float>(rng() % 10);
    for (int l = layers(rng); l > 0; --l) {
      c.push_back(hv(z, z + 0.3F, 10.0F, p.map));
      z += 1.5F;
    }
  }
  return m;
}

TEST(MapMerge, DisjointMapsUniteExactlyAndOverlapsMergeAsIIID) {
  const Params p = params();
  HMap a(p), b(p);
  put(a, {0, 0}, {hv(0.0F, 1.0F, 10.0F, p.map)});
  put(a, {5, -3}, {hv(2.0F, 2.5F, 4.0F, p.map)});
  put(b, {7, 7}, {hv(-1.0F, 0.0F, 3.0F, p.map), hv(3.0F, 4.0F, 6.0F, p.map)});
  // Within the 0.4 m gap of a's [0, 1]: united to [0, 2], 10 + 5 points, density anew.
  put(b, {0, 0}, {hv(1.3F, 2.0F, 5.0F, p.map)});
  const MapMergeStats st = merge_map(a, b);
  EXPECT_EQ(st.columns_added, 1U);
  EXPECT_EQ(st.columns_merged, 1U);
  EXPECT_EQ(st.hvoxels_before, 2U);
  EXPECT_EQ(st.hvoxels_from, 3U);
  EXPECT_EQ(st.hvoxels_after, 4U);
  const ColumnView c = a.column(CellKey{0, 0});
  ASSERT_EQ(c.size(), 1U);
  EXPECT_EQ(c[0], hv(0.0F, 2.0F, 15.0F, p.map));
  ASSERT_EQ(a.column(CellKey{7, 7}).size(), 2U);
  EXPECT_EQ(a.column(CellKey{7, 7})[1], hv(3.0F, 4.0F, 6.0F, p.map));
  EXPECT_EQ(a.column(CellKey{5, -3})[0], hv(2.0F, 2.5F, 4.0F, p.map));
  // Farther than the gap: kept apart.
  HMap d(p);
  put(d, {0, 0}, {hv(2.5F, 3.0F, 2.0F, p.map)});
  merge_map(a, d);
  EXPECT_EQ(a.column(CellKey{0, 0}).size(), 2U);
}

TEST(MapMerge, IntoAnEmptyMapIsACopyAndEmptyChangesNothing) {
  const Params p = params();
  const HMap src = random_map(p, 400, 60, 3);
  HMap empty(p);
  merge_map(empty, src);
  expect_same(src, empty);
  HMap same = random_map(p, 400, 60, 3);
  const MapMergeStats st = merge_map(same, HMap(p));
  EXPECT_EQ(st.hvoxels_from, 0U);
  expect_same(src, same);
}

TEST(MapMerge, RefusesOtherCellSizesAndABudgetItPasses) {
  HMap a(params(0.25));
  const HMap b = random_map(params(0.2), 50, 20, 1);
  EXPECT_THROW(merge_map(a, b), Error);
  const HMap big = random_map(params(), 2000, 400, 2);
  MemoryBudget tiny;
  tiny.bytes = 1024;
  EXPECT_THROW(merge_map(a, big, tiny), Error);
}

TEST(MapShift, WholeCellsAndQuarterTurnsMoveEveryColumnExactly) {
  const Params p = params();
  const HMap m = random_map(p, 300, 50, 7);
  const double s = p.map.cell_size;
  const HMap moved = shifted_map(m, {3 * s, -5 * s, 0.5, 0.0});
  const HMap turned = shifted_map(m, {0.0, 0.0, 0.0, std::numbers::pi / 2});
  EXPECT_EQ(moved.stats().hvoxels, m.stats().hvoxels);
  EXPECT_EQ(turned.stats().hvoxels, m.stats().hvoxels);
  m.for_each_column([&](const CellKey& k, const ColumnView& c) {
    const ColumnView a = moved.column(CellKey{k.i + 3, k.j - 5});
    ASSERT_EQ(a.size(), c.size());
    for (std::size_t q = 0; q < c.size(); ++q) {
      EXPECT_FLOAT_EQ(a[q].z_min, c[q].z_min + 0.5F);
      EXPECT_FLOAT_EQ(a[q].z_max, c[q].z_max + 0.5F);
      EXPECT_EQ(a[q].count, c[q].count);
    }
    // (i + ½, j + ½) turned by 90° is (−j − ½, i + ½): the cell (−j − 1, i).
    const ColumnView t = turned.column(CellKey{-k.j - 1, k.i});
    ASSERT_EQ(t.size(), c.size());
    EXPECT_EQ(t[0], c[0]);
  });
}

TEST(MapShift, ATurnFillsEachCellFromUnderItsCentreMovedBack) {
  // A brute-force twin of the rule: every cell of a box around the result takes the column under
  // its centre moved back, and nothing else is filled.
  const Params p = params();
  const HMap m = random_map(p, 500, 40, 11);
  const PlanarShift shift{1.37, -0.61, 0.0, 0.5236};
  const HMap r = shifted_map(m, shift);
  const double s = p.map.cell_size;
  const double c = std::cos(shift.yaw), sn = std::sin(shift.yaw);
  std::size_t filled = 0;
  for (int i = -60; i <= 60; ++i) {
    for (int j = -60; j <= 60; ++j) {
      const double bx = (i + 0.5) * s - shift.x, by = (j + 0.5) * s - shift.y;
      const ColumnView want = m.column(c * bx + sn * by, -sn * bx + c * by);
      const ColumnView got = r.column(CellKey{i, j});
      ASSERT_EQ(got.size(), want.size()) << i << "," << j;
      if (!want.empty()) {
        EXPECT_EQ(got[0], want[0]);
        ++filled;
      }
    }
  }
  EXPECT_EQ(filled, r.stats().cells);
  // A turn keeps the area: as many columns within a few percent.
  EXPECT_NEAR(static_cast<double>(filled), static_cast<double>(m.stats().cells), 0.05 * static_cast<double>(m.stats().cells));
  EXPECT_THROW((void)shifted_map(m, {NAN, 0.0, 0.0, 0.0}), Error);
  EXPECT_THROW((void)shifted_map(m, {1e12, 0.0, 0.0, 0.0}), Error);
}

/// Points of a wall segment along y at x = wx and a floor patch around (fx, 0), seen from the
/// sensor at `origin` (identity rotation), in its frame.
PointCloud scene_points(const Eigen::Vector3d& origin, double wx, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  PointCloud pts;
  for (int k = 0; k < 4000; ++k) {
    const Eigen::Vector3d w(wx, origin.y() - 4.0 + 8.0 * u(rng), 2.5 * u(rng));
    const Eigen::Vector3d f(origin.x() - 5.0 + 10.0 * u(rng), origin.y() - 5.0 + 10.0 * u(rng), 0.0);
    pts.push_back((w - origin).cast<float>());
    pts.push_back((f - origin).cast<float>());
  }
  return pts;
}

// Sessions farther apart than twice the range: merging their maps gives the map of one run over
// both, exactly. Where they overlap, one run's later scans carve what their free space crosses in
// the earlier ones' HVoxels; a merge cannot (the free space is not kept), so it holds every
// column of the one run's map and at least as many HVoxels.
TEST(MapMerge, SessionsApartMergeToTheOneRunMap) {
  Params p = params(0.2);
  p.map.max_range = 10.0;
  Mapper one(p), first(p), second(p);
  const auto scan = [&](Mapper& m, double x, std::uint32_t seed) {
    const Eigen::Vector3d o(x, 0.0, 1.5);
    Pose T = Pose::Identity();
    T.translation() = o;
    m.integrate(scene_points(o, x + 6.0, seed), T);
  };
  for (int k = 0; k < 3; ++k) {
    scan(one, -30.0 + k, 1 + k);
    scan(first, -30.0 + k, 1 + k);
  }
  for (int k = 0; k < 3; ++k) {
    scan(one, 30.0 + k, 10 + k);
    scan(second, 30.0 + k, 10 + k);
  }
  merge_map(first.map(), second.map());
  expect_same(one.map(), first.map());

  // Overlapping: the second session stands where the first saw its wall from.
  Mapper whole(p), a(p), b(p);
  scan(whole, 0.0, 1);
  scan(a, 0.0, 1);
  scan(whole, 3.0, 2);
  scan(b, 3.0, 2);
  merge_map(a.map(), b.map());
  // Every HVoxel of the one run lies inside one of the merge's: carving only takes away (and may
  // split one HVoxel in two, so the counts are not ordered).
  std::size_t checked = 0;
  whole.map().for_each_column([&](const CellKey& k, const ColumnView& c) {
    const ColumnView m = a.map().column(k);
    for (const HVoxel& v : c) {
      bool inside = false;
      for (const HVoxel& u : m) inside = inside || (u.z_min <= v.z_min + 1e-6F && u.z_max >= v.z_max - 1e-6F);
      EXPECT_TRUE(inside) << k.i << "," << k.j << " [" << v.z_min << ", " << v.z_max << "]";
      ++checked;
    }
  });
  EXPECT_GT(checked, 1000U);
  EXPECT_GT(whole.map().stats().cells, one.map().stats().cells / 4);
}

// A map built in parts, each from the scans that reach its tiles and cut to them, merges to the
// one-run map exactly; a part that skips a scan reaching it from beyond its border does not.
TEST(MapCrop, PartsFromTheScansThatReachThemMergeToTheOneRunMap) {
  Params p = params(0.2);
  p.map.max_range = 10.0;
  const auto scan = [&](Mapper& m, int k) {
    const Eigen::Vector3d o(-12.0 + 2.0 * k, 0.3 * k, 1.5);
    Pose T = Pose::Identity();
    T.translation() = o;
    m.integrate(scene_points(o, o.x() + 6.0, 100 + k), T);
  };
  constexpr int kScans = 12;
  const auto sensor_x = [](int k) { return -12.0 + 2.0 * k; };
  Mapper one(p);
  for (int k = 0; k < kScans; ++k) scan(one, k);

  // Split at tile i = 0 (x = 0): west owns i < 0, east i >= 0. A scan reaches cells within
  // max_range of its sensor; one cell more for the rounding of keys.
  constexpr std::int32_t kFar = 1 << 20;
  const TileRange west{-kFar, -kFar, 0, kFar};
  const TileRange east{0, -kFar, kFar, kFar};
  const double reach = p.map.max_range + p.map.cell_size;
  Mapper west_scans(p), east_scans(p), west_short(p);
  for (int k = 0; k < kScans; ++k) {
    if (sensor_x(k) < reach) scan(west_scans, k);
    if (sensor_x(k) >= -reach) scan(east_scans, k);
    if (sensor_x(k) < 0.0) scan(west_short, k);
  }
  HMap merged = crop_map(west_scans.map(), west);
  const HMap east_part = crop_map(east_scans.map(), east);
  const MapMergeStats st = merge_map(merged, east_part);
  EXPECT_EQ(st.columns_merged, 0U);  // disjoint tiles: every column copied
  EXPECT_GT(st.columns_added, 1000U);
  expect_same(one.map(), merged);
  expect_same(merged, one.map());

  // Without the scans east of the border that reach west of it, the west part is not the one run's.
  const HMap short_part = crop_map(west_short.map(), west);
  const HMap west_part = crop_map(one.map(), west);
  std::size_t differ = 0;
  west_part.for_each_column([&](const CellKey& k, const ColumnView& c) {
    const ColumnView o = short_part.column(k);
    differ += (o.size() != c.size() || !std::equal(c.begin(), c.end(), o.begin())) ? 1 : 0;
  });
  EXPECT_GT(differ, 0U);
}

TEST(MapCrop, KeepsOnlyTheRangeAndRefusesAnInvertedOne) {
  const Params p = params();
  const HMap m = random_map(p, 400, 60, 7);
  const TileRange range{-1, 0, 2, 3};
  const HMap cut = crop_map(m, range);
  std::size_t inside = 0;
  m.for_each_column([&](const CellKey& k, const ColumnView& c) {
    const ColumnView o = cut.column(k);
    if (range.contains(HMap::tile_of(k))) {
      ++inside;
      ASSERT_EQ(o.size(), c.size());
      EXPECT_TRUE(std::equal(c.begin(), c.end(), o.begin()));
    } else {
      EXPECT_TRUE(o.empty()) << k.i << "," << k.j;
    }
  });
  EXPECT_GT(inside, 0U);
  EXPECT_EQ(cut.stats().cells, inside);
  EXPECT_EQ(cut.params().map.cell_size, p.map.cell_size);
  EXPECT_TRUE(crop_map(m, TileRange{3, 3, 3, 9}).empty());  // no tile
  EXPECT_TRUE(crop_map(HMap(p), range).empty());
  EXPECT_THROW((void)crop_map(m, TileRange{2, 0, 1, 3}), Error);
}


// Loop closure's rebuild (map_rebuild.hpp): a corridor of 36 scans 2 m apart, the last eight
// corrected sideways and turned. Rebuilding the tiles the moved scans reach gives, column for
// column, the map built in one go at the result's poses, while most scans are not read again.
class TileRebuildTest : public ::testing::Test {
 protected:
  static constexpr int kScans = 36;
  Params p = params(0.2);
  std::vector<PointCloud> scans;
  PoseList built_at;

  void SetUp() override {
    p.map.max_range = 8.0;
    for (int k = 0; k < kScans; ++k) {
      const Eigen::Vector3d o(2.0 * k, 0.0, 1.5);
      scans.push_back(scene_points(o, o.x() + 4.0, 300 + k));
      Pose T = Pose::Identity();
      T.translation() = o;
      built_at.push_back(T);
    }
  }
  HMap build(const PoseList& poses) const {
    Mapper m(p);
    for (int k = 0; k < kScans; ++k) m.integrate(scans[k], poses[k]);
    return std::move(m.map());
  }
  std::function<void(std::size_t, PointCloud&)> reader(std::vector<int>* read = nullptr) const {
    return [this, read](std::size_t k, PointCloud& out) {
      if (read) read->push_back(static_cast<int>(k));
      out = scans[k];
    };
  }
};

TEST_F(TileRebuildTest, MovedTilesRebuiltEqualTheWholeMapBuiltAtTheCorrectedPoses) {
  const HMap built = build(built_at);
  PoseList corrected = built_at;
  for (int k = 28; k < kScans; ++k) {  // 5 cm more sideways per scan, and 0.2 degrees more turned
    corrected[k].translation().y() += 0.05 * (k - 27);
    corrected[k].linear() = Eigen::AngleAxisd(0.0035 * (k - 27), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }
  corrected[3].translation().x() += 0.001;  // within the tolerance: kept where it was built
  std::vector<int> read;
  const TileRebuild r = rebuild_moved_tiles(built, built_at, corrected, 0.01, reader(&read));
  EXPECT_EQ(r.scans_moved, 8U);
  EXPECT_TRUE(r.T_map_sensor[3].isApprox(built_at[3]));
  EXPECT_TRUE(r.T_map_sensor[30].isApprox(corrected[30]));
  // The first moved scan (x = 56, cell 280) reaches back 42 cells, to tile (280 - 42) >> 3 = 29;
  // the scan at x = 38 reaches forward to tile (190 + 42) >> 3 = 29 too: the scans from it on
  // (k >= 19) are read again, the 19 before them are not.
  EXPECT_EQ(r.scans_integrated, read.size());
  EXPECT_EQ(read.front(), 19);
  EXPECT_EQ(read.size(), 17U);
  EXPECT_GT(r.tiles_kept, 100U);
  EXPECT_GT(r.tiles_rebuilt, 100U);
  const HMap whole = build(r.T_map_sensor);
  expect_same(whole, r.map);
  expect_same(r.map, whole);
  // The map did change where the scans moved: the old one is not the new one.
  std::size_t differ = 0;
  whole.for_each_column([&](const CellKey& k, const ColumnView& c) {
    const ColumnView o = built.column(k);
    differ += (o.size() != c.size() || !std::equal(c.begin(), c.end(), o.begin())) ? 1 : 0;
  });
  EXPECT_GT(differ, 500U);
}

TEST_F(TileRebuildTest, RebuildingOnlyTheNewSquaresWouldMissWhatTheScansLeftBehind) {
  // The scans moved 20 m sideways, past the 8.4 m their squares reach: their old tiles must be
  // rebuilt too (to lose their HVoxels);
  // with a tolerance above the move, nothing is rebuilt and the old map comes back as it was.
  const HMap built = build(built_at);
  PoseList corrected = built_at;
  for (int k = 30; k < kScans; ++k) corrected[k].translation().y() += 20.0;
  const TileRebuild r = rebuild_moved_tiles(built, built_at, corrected, 0.0, reader());
  EXPECT_EQ(r.scans_moved, 6U);
  expect_same(build(corrected), r.map);
  expect_same(r.map, build(corrected));
  std::vector<int> read;
  const TileRebuild kept = rebuild_moved_tiles(built, built_at, corrected, 20.5, reader(&read));
  EXPECT_EQ(kept.scans_moved, 0U);
  EXPECT_TRUE(read.empty());
  EXPECT_EQ(kept.tiles_rebuilt, 0U);
  expect_same(built, kept.map);
  expect_same(kept.map, built);
}

TEST_F(TileRebuildTest, RefusesMismatchedPosesNonFiniteOnesAndABadTolerance) {
  const HMap built = build(built_at);
  PoseList fewer(built_at.begin(), built_at.end() - 1);
  EXPECT_THROW((void)rebuild_moved_tiles(built, built_at, fewer, 0.01, reader()), Error);
  PoseList bad = built_at;
  bad[5].translation().x() = NAN;
  EXPECT_THROW((void)rebuild_moved_tiles(built, built_at, bad, 0.01, reader()), Error);
  bad[5].translation().x() = 1e12;  // beyond the key range
  EXPECT_THROW((void)rebuild_moved_tiles(built, built_at, bad, 0.01, reader()), Error);
  EXPECT_THROW((void)rebuild_moved_tiles(built, built_at, built_at, -1.0, reader()), Error);
  EXPECT_THROW((void)rebuild_moved_tiles(built, built_at, built_at, NAN, reader()), Error);
  // No scans: an empty map.
  const TileRebuild none = rebuild_moved_tiles(HMap(p), {}, {}, 0.01, reader());
  EXPECT_TRUE(none.map.empty());
  EXPECT_EQ(none.scans_integrated, 0U);
}

TEST(PoseDisplacementBound, IsTheShiftPlusTheTurnAtTheRange) {
  Pose a = Pose::Identity();
  Pose b = Pose::Identity();
  b.translation() = Eigen::Vector3d(3.0, 4.0, 0.0);
  EXPECT_NEAR(pose_displacement_bound(a, b, 50.0), 5.0, 1e-12);
  b.linear() = Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_NEAR(pose_displacement_bound(a, b, 10.0), 5.1, 1e-9);
  EXPECT_NEAR(pose_displacement_bound(b, b, 10.0), 0.0, 1e-6);
  // The square of tiles a scan reaches: 8 m / 0.2 m = 40 cells, +2, about the sensor's cell 0.
  Params p = params(0.2);
  p.map.max_range = 8.0;
  const TileSquare s = scan_tile_square(p.map, a);
  EXPECT_EQ(s.lo.i, HMap::tile_of({-42, 0}).i);
  EXPECT_EQ(s.hi.i, HMap::tile_of({42, 0}).i);
  EXPECT_EQ(s.lo.j, s.lo.i);
}

}  // namespace map_merge_test
}  // namespace hmap
