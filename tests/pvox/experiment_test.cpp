#include "hmap/pvox/boxes_experiment.hpp"

#include <gtest/gtest.h>

#include "hmap/pvox/mapper.hpp"
#include "hmap/pvox/measure.hpp"
#include "hmap/pvox/serialize.hpp"

namespace hmap::pvox {
namespace {

// The seed's experiment end to end at a small size (1° beams, 31 sweep steps): RBF registers
// every position to a few millimetres and its map gives the nine edges; BRF drifts.
TEST(BoxesExperiment, RunsEndToEndAtASmallSize) {
  BoxesExperimentParams sp;
  sp.seed = 4;
  sp.angular_step_deg = 1.0;
  sp.sweep_steps = 61;
  const BoxesRecording rec = simulate_boxes(sp);
  ASSERT_EQ(rec.scans.size(), 5U);
  EXPECT_EQ(rec.T_world_true[0].translation(), rec.T_world_nominal[0].translation());
  EXPECT_GT((rec.T_world_true[4].translation() - rec.T_world_nominal[4].translation()).norm(), 0.0);

  double average[2] = {0.0, 0.0};
  double worst_position_error[2] = {0.0, 0.0};
  for (const FilterKind kind : {FilterKind::kRecursive, FilterKind::kNaive}) {
    PvoxParams p;
    p.filter.kind = kind;
    p.insert.min_range = 0.1;
    p.insert.max_range = 30.0;
    PvoxMapper mapper(p);
    const int f = kind == FilterKind::kRecursive ? 0 : 1;
    for (std::size_t k = 0; k < rec.scans.size(); ++k) {
      const auto r = mapper.add_scan(rec.scans[k], rec.commands[k]);
      const double error = (r.T_map_sensor.translation() - rec.T_world_true[k].translation()).norm();
      worst_position_error[f] = std::max(worst_position_error[f], error);
    }
    const auto edges = measure_boxes_edges(mapper.map());
    ASSERT_EQ(edges.size(), 9U);
    EXPECT_EQ(edges[0].name, "AB");
    EXPECT_EQ(edges[8].name, "JK");
    average[f] = average_accuracy(edges);
    if (kind == FilterKind::kRecursive) {
      for (const auto& e : edges) EXPECT_TRUE(e.measured.has_value()) << e.name;
      // The binary map is far smaller than the raw points.
      EXPECT_LT(encode_binary(mapper.map()).size() * 5, rec.scans.size() * rec.scans[0].size() * 24);
    }
  }
  EXPECT_LT(worst_position_error[0], 0.01);
  EXPECT_GT(worst_position_error[1], 0.05);
  EXPECT_GT(average[0], 0.9);
  EXPECT_GT(average[0], average[1]);
}

TEST(Measure, PlaneAndEndOfASyntheticFace) {
  // A face x = 0.3 covering y in [0.1, 0.5], z in [0, 0.4], sampled every 5 mm.
  VoxelMap map(0.06);
  for (double y = 0.1; y <= 0.5 + 1e-9; y += 0.005) {
    for (double z = 0.0; z <= 0.4 + 1e-9; z += 0.005) map.add_hit(Eigen::Vector3d(0.3, y, z));
  }
  FaceQuery face{0, Eigen::AlignedBox3d(Eigen::Vector3d(0.2, 0.0, -0.1), Eigen::Vector3d(0.4, 0.7, 0.5))};
  ASSERT_TRUE(measure_plane(map, face).has_value());
  EXPECT_NEAR(*measure_plane(map, face), 0.3, 1e-4);
  EXPECT_NEAR(*measure_extent(map, face, 1, -1), 0.1, 0.004);
  EXPECT_NEAR(*measure_extent(map, face, 1, +1), 0.5, 0.004);
  EXPECT_NEAR(*measure_extent(map, face, 2, +1), 0.4, 0.004);
  face.region = Eigen::AlignedBox3d(Eigen::Vector3d(5, 5, 5), Eigen::Vector3d(6, 6, 6));
  EXPECT_FALSE(measure_plane(map, face).has_value());
  EXPECT_FALSE(measure_extent(map, face, 1, -1).has_value());
}

// The plane is the weighted median of the flat voxels' means, by hand: three voxels of a face x ≈
// 0.3 with 30, 100 and 30 points at x = 0.31, 0.32, 0.34 (each flat: weight ∝ points). Sorted, the
// weights run 30, 130, 160 of 160: the median is 0.32 (the minimum would be 0.31, the mean 0.32375).
TEST(Measure, PlaneIsTheWeightedMedianOfTheFlatVoxels) {
  VoxelMap map(0.06);
  const auto fill = [&](double x, double y0, int count) {
    for (int k = 0; k < count; ++k) map.add_hit(Eigen::Vector3d(x, y0 + 0.04 * (k % 10) / 9.0, 0.01 + 0.04 * (k / 10) / 9.0));
  };
  fill(0.31, 0.01, 30);   // voxel y in [0, 0.06)
  fill(0.32, 0.07, 100);  // [0.06, 0.12)
  fill(0.34, 0.13, 30);   // [0.12, 0.18)
  const FaceQuery face{0, Eigen::AlignedBox3d(Eigen::Vector3d(0.2, -0.1, -0.1), Eigen::Vector3d(0.4, 0.3, 0.2))};
  ASSERT_TRUE(measure_plane(map, face).has_value());
  EXPECT_NEAR(*measure_plane(map, face), 0.32, 1e-6);  // moments are kept in float
}

}  // namespace
}  // namespace hmap::pvox
