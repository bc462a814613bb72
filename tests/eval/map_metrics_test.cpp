#include "hmap/eval/map_metrics.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

using Voxel = std::tuple<int, int, long>;  // (i, j, l)

HMap make_map() { return HMap(outdoor_preset()); }  // 0.25 m cells

/// A ground with a slope and a wall, `n` points over x, y in [-2, 2).
PointCloud surface(std::mt19937& gen, std::size_t n) {
  std::uniform_real_distribution<float> u(-2.0F, 2.0F);
  std::uniform_real_distribution<float> h(0.0F, 2.5F);
  PointCloud points;
  for (std::size_t k = 0; k < n; ++k) {
    const float x = u(gen);
    const float y = u(gen);
    if (k % 4 == 0) {
      points.emplace_back(1.1F, y, h(gen));  // wall at x = 1.1
    } else {
      points.emplace_back(x, y, 0.1F * x + 0.05F * std::sin(3.0F * y));
    }
  }
  return points;
}

std::set<Voxel> voxelize(const HMap& map, const PointCloud& points, double h) {
  std::set<Voxel> voxels;
  for (const Point3f& p : points) {
    const CellKey key = *map.key_of(p.x(), p.y());
    voxels.insert({key.i, key.j, static_cast<long>(std::floor(p.z() / h))});
  }
  return voxels;
}

/// Adds HVoxels covering exactly `voxels` (each run of consecutive voxels of a column becomes one
/// HVoxel, kept 1 % of a voxel inside its ends so it overlaps no neighbouring voxel).
void cover(HMap& map, const std::set<Voxel>& voxels, double h) {
  std::map<std::pair<int, int>, std::vector<long>> columns;
  for (const auto& [i, j, l] : voxels) columns[{i, j}].push_back(l);  // sorted by the set
  const double eps = 0.01 * h;
  for (const auto& [ij, ls] : columns) {
    TileColumn column = map.column_for_update(CellKey{ij.first, ij.second});
    std::size_t a = 0;
    while (a < ls.size()) {
      std::size_t b = a;
      while (b + 1 < ls.size() && ls[b + 1] == ls[b] + 1) ++b;
      column.push_back({static_cast<float>(static_cast<double>(ls[a]) * h + eps),
                        static_cast<float>(static_cast<double>(ls[b] + 1) * h - eps), 10.0F, 1.0F});
      a = b + 1;
    }
  }
}

/// The brute-force twin: every voxel enumerated, every neighbour looked up.
OccupancyScores occupancy_twin(const HMap& map, const PointCloud& truth, double h, int k) {
  const std::set<Voxel> truth_voxels = voxelize(map, truth, h);
  std::set<Voxel> map_voxels;
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    for (const HVoxel& v : column) {
      for (auto l = static_cast<long>(std::floor(v.z_min / h)); l <= static_cast<long>(std::floor(v.z_max / h)); ++l) {
        map_voxels.insert({key.i, key.j, l});
      }
    }
  });
  const auto near = [k](const std::set<Voxel>& set, const Voxel& v) {
    for (int di = -k; di <= k; ++di)
      for (int dj = -k; dj <= k; ++dj)
        for (long dl = -k; dl <= k; ++dl)
          if (set.count({std::get<0>(v) + di, std::get<1>(v) + dj, std::get<2>(v) + dl}) > 0) return true;
    return false;
  };
  OccupancyScores s;
  s.truth_voxels = truth_voxels.size();
  s.map_voxels = map_voxels.size();
  for (const Voxel& v : truth_voxels) s.truth_voxels_recalled += near(map_voxels, v) ? 1 : 0;
  for (const Voxel& v : map_voxels) s.map_voxels_matched += near(truth_voxels, v) ? 1 : 0;
  return s;
}

/// Random map: a few sorted, disjoint HVoxels in random cells around the truth.
HMap random_map(std::mt19937& gen) {
  HMap map = make_map();
  std::uniform_int_distribution<int> cell(-9, 8);
  std::uniform_real_distribution<float> gap(0.05F, 0.6F);
  std::uniform_real_distribution<float> len(0.0F, 0.8F);
  for (int c = 0; c < 150; ++c) {
    TileColumn column = map.column_for_update(CellKey{cell(gen), cell(gen)});
    if (!column.empty()) continue;
    float z = -0.6F + gap(gen);
    for (int n = 0; n < 3; ++n) {
      const float top = z + len(gen);
      column.push_back({z, top, 5.0F, 1.0F});
      z = top + gap(gen);
    }
  }
  return map;
}

TEST(MapMetricsTest, MapEqualToTheTruthScoresOne) {
  std::mt19937 gen(11);
  const PointCloud truth = surface(gen, 3000);
  HMap map = make_map();
  const double h = map.cell_size();
  cover(map, voxelize(map, truth, h), h);
  const MapMetrics m = evaluate_map(map, truth);
  EXPECT_FALSE(m.map_empty);
  EXPECT_FALSE(m.truth_empty);
  EXPECT_EQ(m.voxel_height_m, 0.25);
  EXPECT_GT(m.exact.truth_voxels, 100U);
  EXPECT_EQ(m.exact.map_voxels, m.exact.truth_voxels);
  EXPECT_EQ(m.exact.precision, 1.0);
  EXPECT_EQ(m.exact.recall, 1.0);
  EXPECT_EQ(m.exact.f_score, 1.0);
  EXPECT_EQ(m.tolerant.tolerance_voxels, 1);
  EXPECT_EQ(m.tolerant.precision, 1.0);
  EXPECT_EQ(m.tolerant.recall, 1.0);
  // Recovered points sit at cell centres: within half a cell diagonal, plus a voxel in z.
  EXPECT_LT(m.chamfer.accuracy_m, 0.25);
  EXPECT_LT(m.chamfer.completeness_m, 0.25);
  EXPECT_EQ(m.chamfer.threshold_m, 0.25);
  EXPECT_GT(m.chamfer.completeness_within, 0.9);
  EXPECT_EQ(m.hvoxels_capped, 0U);
}

TEST(MapMetricsTest, MapMissingHalfTheTruthRecallsHalf) {
  std::mt19937 gen(12);
  const PointCloud truth = surface(gen, 4000);
  HMap map = make_map();
  const double h = map.cell_size();
  const std::set<Voxel> all = voxelize(map, truth, h);
  std::set<Voxel> left;  // y < 0: cells j < 0 (ground and wall alike)
  for (const Voxel& v : all) {
    if (std::get<1>(v) < 0) left.insert(v);
  }
  cover(map, left, h);
  const MapMetrics m = evaluate_map(map, truth);
  EXPECT_EQ(m.exact.truth_voxels_recalled, left.size());
  EXPECT_NEAR(m.exact.recall, static_cast<double>(left.size()) / static_cast<double>(all.size()), 1e-12);
  EXPECT_NEAR(m.exact.recall, 0.5, 0.05);
  EXPECT_EQ(m.exact.precision, 1.0);
  EXPECT_NEAR(m.exact.f_score, 2.0 * m.exact.recall / (1.0 + m.exact.recall), 1e-12);
  EXPECT_GT(m.tolerant.recall, m.exact.recall);  // the column next to the border counts too
}

TEST(MapMetricsTest, OccupancyMatchesTheBruteForceTwin) {
  std::mt19937 gen(13);
  for (int trial = 0; trial < 5; ++trial) {
    const PointCloud truth = surface(gen, 800);
    const HMap map = random_map(gen);
    for (const double h : {0.25, 0.1}) {
      for (const int k : {0, 1, 2}) {
        const OccupancyScores fast = occupancy_scores(map, truth, h, k);
        const OccupancyScores twin = occupancy_twin(map, truth, h, k);
        EXPECT_EQ(fast.tolerance_voxels, k);
        EXPECT_EQ(fast.truth_voxels, twin.truth_voxels) << "h " << h << " k " << k;
        EXPECT_EQ(fast.truth_voxels_recalled, twin.truth_voxels_recalled) << "h " << h << " k " << k;
        EXPECT_EQ(fast.map_voxels, twin.map_voxels) << "h " << h << " k " << k;
        EXPECT_EQ(fast.map_voxels_matched, twin.map_voxels_matched) << "h " << h << " k " << k;
        if (k == 0) {  // a non-trivial case: some but not all recalled and matched
          EXPECT_GT(fast.recall, 0.0);
          EXPECT_LT(fast.recall, 1.0);
          EXPECT_GT(fast.precision, 0.0);
          EXPECT_LT(fast.precision, 1.0);
        }
      }
    }
  }
}

TEST(MapMetricsTest, HugeHVoxelIsCountedNotEnumerated) {
  HMap map = make_map();
  map.column_for_update(CellKey{0, 0}).push_back({-1.0e6F, 1.0e6F, 10.0F, 1.0F});
  const PointCloud truth{Point3f(0.1F, 0.1F, 0.3F)};
  const auto start = std::chrono::steady_clock::now();
  const MapMetrics m = evaluate_map(map, truth);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
  EXPECT_EQ(m.exact.map_voxels, 8000001U);  // l = -4e6..4e6: z_max = 1e6 m touches voxel 4e6
  EXPECT_EQ(m.exact.map_voxels_matched, 1U);
  EXPECT_EQ(m.exact.recall, 1.0);
  EXPECT_EQ(m.tolerant.map_voxels_matched, 3U);
  EXPECT_EQ(m.hvoxels_capped, 1U);
  EXPECT_EQ(m.chamfer.map_points, MapEvalParams{}.max_points_per_hvoxel);
}

TEST(MapMetricsTest, RecoveredPointsEqualRecoverPointsUnderTheCap) {
  std::mt19937 gen(14);
  const HMap map = random_map(gen);
  for (const double step : {0.25, 0.07}) {
    const RecoveredPoints capped = recover_points_capped(map, step, 4096);
    EXPECT_EQ(capped.capped_hvoxels, 0U);
    EXPECT_EQ(capped.points_map, recover_points(map, step));
  }
  // Capped at 3: HVoxels needing more get z_min, the middle and z_max.
  HMap tall = make_map();
  tall.column_for_update(CellKey{2, 3}).push_back({1.0F, 2.0F, 10.0F, 1.0F});
  const RecoveredPoints three = recover_points_capped(tall, 0.25, 3);
  EXPECT_EQ(three.capped_hvoxels, 1U);
  ASSERT_EQ(three.points_map.size(), 3U);
  EXPECT_FLOAT_EQ(three.points_map[0].z(), 1.0F);
  EXPECT_FLOAT_EQ(three.points_map[1].z(), 1.5F);
  EXPECT_FLOAT_EQ(three.points_map[2].z(), 2.0F);
  EXPECT_FLOAT_EQ(three.points_map[1].x(), 0.625F);
}

double nearest_twin(const Point3f& q, const PointCloud& targets) {
  double best = std::numeric_limits<double>::infinity();
  for (const Point3f& t : targets) best = std::min(best, static_cast<double>((q - t).norm()));
  return best;
}

TEST(MapMetricsTest, ChamferMatchesTheBruteForceTwin) {
  std::mt19937 gen(15);
  std::uniform_real_distribution<float> u(-3.0F, 3.0F);
  for (const auto& [na, nb] : {std::pair{300, 200}, std::pair{1, 50}, std::pair{2500, 3000}}) {
    PointCloud a;
    PointCloud b;
    for (int n = 0; n < na; ++n) a.emplace_back(u(gen), u(gen), 0.3F * u(gen));
    for (int n = 0; n < nb; ++n) b.emplace_back(u(gen), u(gen), 0.3F * u(gen));
    const double threshold = 0.3;
    const ChamferScores s = chamfer_scores(a, b, threshold);
    double acc = 0.0;
    double acc_within = 0.0;
    for (const Point3f& p : a) {
      const double d = nearest_twin(p, b);
      acc += d;
      acc_within += d <= threshold ? 1.0 : 0.0;
    }
    double comp = 0.0;
    double comp_within = 0.0;
    for (const Point3f& p : b) {
      const double d = nearest_twin(p, a);
      comp += d;
      comp_within += d <= threshold ? 1.0 : 0.0;
    }
    EXPECT_EQ(s.map_points, a.size());
    EXPECT_EQ(s.truth_points, b.size());
    EXPECT_NEAR(s.accuracy_m, acc / na, 1e-5);
    EXPECT_NEAR(s.completeness_m, comp / nb, 1e-5);
    EXPECT_NEAR(s.chamfer_m, 0.5 * (acc / na + comp / nb), 1e-5);
    EXPECT_NEAR(s.accuracy_within, acc_within / na, 1e-12);
    EXPECT_NEAR(s.completeness_within, comp_within / nb, 1e-12);
  }
}

TEST(MapMetricsTest, EmptyInputsGiveDefinedResults) {
  std::mt19937 gen(16);
  const PointCloud truth = surface(gen, 200);
  const HMap empty = make_map();
  const MapMetrics no_map = evaluate_map(empty, truth);
  EXPECT_TRUE(no_map.map_empty);
  EXPECT_FALSE(no_map.truth_empty);
  EXPECT_EQ(no_map.exact.map_voxels, 0U);
  EXPECT_EQ(no_map.exact.precision, 0.0);
  EXPECT_EQ(no_map.exact.recall, 0.0);
  EXPECT_EQ(no_map.exact.f_score, 0.0);
  EXPECT_TRUE(std::isnan(no_map.chamfer.accuracy_m));
  EXPECT_TRUE(std::isnan(no_map.chamfer.chamfer_m));
  EXPECT_EQ(no_map.chamfer.completeness_within, 0.0);

  HMap map = make_map();
  cover(map, voxelize(map, truth, 0.25), 0.25);
  const MapMetrics no_truth = evaluate_map(map, PointCloud{});
  EXPECT_FALSE(no_truth.map_empty);
  EXPECT_TRUE(no_truth.truth_empty);
  EXPECT_EQ(no_truth.exact.truth_voxels, 0U);
  EXPECT_GT(no_truth.exact.map_voxels, 0U);
  EXPECT_EQ(no_truth.exact.precision, 0.0);
  EXPECT_EQ(no_truth.exact.recall, 0.0);
  EXPECT_TRUE(std::isnan(no_truth.chamfer.completeness_m));

  const MapMetrics nothing = evaluate_map(empty, PointCloud{});
  EXPECT_TRUE(nothing.map_empty && nothing.truth_empty);
  EXPECT_EQ(nothing.tolerant.f_score, 0.0);
  EXPECT_EQ(chamfer_scores({}, {}, 0.1).map_points, 0U);
}

TEST(MapMetricsTest, BadInputsThrow) {
  const HMap map = make_map();
  const PointCloud truth{Point3f(0, 0, 0)};
  PointCloud nan_truth{Point3f(0, std::numeric_limits<float>::quiet_NaN(), 0)};
  EXPECT_THROW((void)evaluate_map(map, nan_truth), Error);
  EXPECT_THROW((void)evaluate_map(map, PointCloud{Point3f(1e30F, 0, 0)}), Error);
  MapEvalParams p;
  p.voxel_height = -0.1;
  EXPECT_THROW((void)evaluate_map(map, truth, p), Error);
  p = {};
  p.tolerance_voxels = -1;
  EXPECT_THROW((void)evaluate_map(map, truth, p), Error);
  p.tolerance_voxels = 11;
  EXPECT_THROW((void)evaluate_map(map, truth, p), Error);
  p = {};
  p.distance_threshold = std::numeric_limits<double>::infinity();
  EXPECT_THROW((void)evaluate_map(map, truth, p), Error);
  p = {};
  p.max_points_per_hvoxel = 1;
  EXPECT_THROW((void)evaluate_map(map, truth, p), Error);
  EXPECT_THROW((void)occupancy_scores(map, truth, 0.0, 0), Error);
  EXPECT_THROW((void)chamfer_scores(truth, nan_truth, 0.1), Error);
  EXPECT_THROW((void)chamfer_scores(truth, truth, -0.1), Error);
  HMap reversed = make_map();
  reversed.column_for_update(CellKey{0, 0}).push_back({2.0F, 1.0F, 1.0F, 1.0F});
  EXPECT_THROW((void)evaluate_map(reversed, truth), Error);
}

}  // namespace
}  // namespace hmap
