#include "hmap/pvox/measure.hpp"

#include <gtest/gtest.h>

#include <random>

#include "hmap/core/error.hpp"

namespace hmap::pvox {
namespace {

/// Samples the rectangle of the plane `axis` = `c` spanning [lo, hi] on the two other axes (in
/// axis order) every `step`, with N(0, noise²) on each coordinate (fixed seed).
void add_rect(VoxelMap& map, int axis, double c, Eigen::Vector2d lo, Eigen::Vector2d hi, double step, double noise,
              std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const int u = axis == 0 ? 1 : 0;
  const int v = axis == 2 ? 1 : 2;
  for (double a = lo.x(); a <= hi.x() + 1e-9; a += step) {
    for (double b = lo.y(); b <= hi.y() + 1e-9; b += step) {
      Eigen::Vector3d p;
      p[axis] = c + noise * normal(rng);
      p[u] = a + noise * normal(rng);
      p[v] = b + noise * normal(rng);
      map.add_hit(p);
    }
  }
}

/// A floor z = 0 (x, y in [0, 1]), a wall y = 0.8 (x in [0, 1], z in [0, 0.6]) and a box whose
/// top is at z = `top` over x in [0.2, 0.5], y in [0.3, 0.5], with its front (y = 0.3) and right
/// side (x = 0.5); 5 mm samples, 2 mm noise, voxels of 58.6 mm as in the experiment.
VoxelMap scene(double top, bool with_top = true) {
  VoxelMap map(0.0586);
  std::mt19937 rng(7);
  add_rect(map, 2, 0.0, {0.0, 0.0}, {1.0, 1.0}, 0.005, 0.002, rng);
  add_rect(map, 1, 0.8, {0.0, 0.0}, {1.0, 0.6}, 0.005, 0.002, rng);
  if (with_top) add_rect(map, 2, top, {0.2, 0.3}, {0.5, 0.5}, 0.005, 0.002, rng);
  add_rect(map, 1, 0.3, {0.2, 0.0}, {0.5, top}, 0.005, 0.002, rng);
  add_rect(map, 0, 0.5, {0.3, 0.0}, {0.5, top}, 0.005, 0.002, rng);
  return map;
}

std::vector<double> coordinates(const std::vector<DetectedPlane>& planes) {
  std::vector<double> out;
  for (const auto& p : planes) out.push_back(p.coordinate);
  return out;
}

// The planes of a known scene are found where they are, with no position given: z 0 and 0.25,
// y 0.3 and 0.8, x 0.5 (to 2 mm: the mean of ≥ 40 points with 2 mm noise is within 1 mm); the
// wall does not appear among the z planes, nor the floor among the y planes.
TEST(DetectPlanes, FindsTheKnownPlanesWithoutBeingToldWhere) {
  const VoxelMap map = scene(0.25);
  const auto z = detect_planes(map, 2);
  ASSERT_EQ(z.size(), 2U) << ::testing::PrintToString(coordinates(z));
  EXPECT_NEAR(z[0].coordinate, 0.0, 0.002);
  EXPECT_NEAR(z[1].coordinate, 0.25, 0.002);
  const auto y = detect_planes(map, 1);
  ASSERT_EQ(y.size(), 2U) << ::testing::PrintToString(coordinates(y));
  EXPECT_NEAR(y[0].coordinate, 0.3, 0.002);
  EXPECT_NEAR(y[1].coordinate, 0.8, 0.002);
  const auto x = detect_planes(map, 0);
  ASSERT_EQ(x.size(), 1U) << ::testing::PrintToString(coordinates(x));
  EXPECT_NEAR(x[0].coordinate, 0.5, 0.002);

  // Support: the floor (1 m²) holds far more than the box top (0.06 m²), which still has a few
  // dozen points per voxel.
  EXPECT_GT(z[0].flat_voxels, 5 * z[1].flat_voxels);
  EXPECT_GE(z[1].flat_voxels, 4U);
  EXPECT_GT(z[1].points, 40 * z[1].flat_voxels);
  // Extent and ends of the box top (x 0.2..0.5, y 0.3..0.5): from its own voxels, within a
  // quarter of a voxel (the end is the outermost voxel's mean ± √3σ, exact for points uniform over
  // the covered part; a voxel that also holds the top of the perpendicular face is not uniform).
  const double tolerance = 0.25 * map.edge();
  EXPECT_NEAR(*plane_end(map, z[1], 0, -1), 0.2, tolerance);
  EXPECT_NEAR(*plane_end(map, z[1], 0, +1), 0.5, tolerance);
  EXPECT_NEAR(*plane_end(map, z[1], 1, -1), 0.3, tolerance);
  EXPECT_NEAR(*plane_end(map, z[1], 1, +1), 0.5, tolerance);
  EXPECT_NEAR(z[1].extent.min().x(), 0.2, tolerance);
  EXPECT_NEAR(z[1].extent.max().x(), 0.5, tolerance);
  // The wall's top end (z 0.6) and the floor's far end (x 1.0).
  EXPECT_NEAR(*plane_end(map, y[1], 2, +1), 0.6, tolerance);
  EXPECT_NEAR(*plane_end(map, z[0], 0, +1), 1.0, tolerance);
}

// A face 7 cm from where it should be (the old ±5 cm window around the nominal face would not
// have seen it) is found where it is, and matched with its face: nominal z 0, 0.25 and 0.6 give
// the top a gate of min(0.25, 0.35) / 2 = 0.125 m.
TEST(DetectPlanes, AFaceFarOutsideTheOldWindowIsStillMeasured) {
  const VoxelMap map = scene(0.32);
  const auto z = detect_planes(map, 2);
  const std::vector<double> nominal = {0.0, 0.25, 0.6};
  EXPECT_DOUBLE_EQ(face_gate(nominal, 1), 0.125);
  const auto match = associate_faces(z, nominal);
  ASSERT_TRUE(match[0].has_value());
  ASSERT_TRUE(match[1].has_value());
  EXPECT_FALSE(match[2].has_value());
  EXPECT_NEAR(z[*match[1]].coordinate - z[*match[0]].coordinate, 0.32, 0.003);
}

// Without the box top, the face is reported missing, not measured on something else: the floor
// is 0.25 m away, outside the top's gate.
TEST(DetectPlanes, ARemovedFaceIsMissing) {
  const VoxelMap map = scene(0.25, false);
  const auto z = detect_planes(map, 2);
  ASSERT_EQ(z.size(), 1U) << ::testing::PrintToString(coordinates(z));
  const auto match = associate_faces(z, {0.0, 0.25, 0.6});
  EXPECT_TRUE(match[0].has_value());
  EXPECT_FALSE(match[1].has_value());
}

// The plane is the weighted median of its flat voxels, by hand: three voxels of a face x ≈ 0.32
// with 30, 100 and 30 points at x = 0.31, 0.32, 0.34 (each flat: weight ∝ points), one cluster
// with a 30 mm kernel. Sorted, the weights run 30, 130, 160 of 160: the median is 0.32 (the minimum
// would be 0.31, the mean 0.32375).
TEST(DetectPlanes, PlaneIsTheWeightedMedianOfTheFlatVoxels) {
  VoxelMap map(0.06);
  const auto fill = [&](double x, double y0, int count) {
    for (int k = 0; k < count; ++k) map.add_hit(Eigen::Vector3d(x, y0 + 0.04 * (k % 10) / 9.0, 0.01 + 0.04 * (k / 10) / 9.0));
  };
  fill(0.31, 0.01, 30);   // voxel y in [0, 0.06)
  fill(0.32, 0.07, 100);  // [0.06, 0.12)
  fill(0.34, 0.13, 30);   // [0.12, 0.18)
  PlaneDetectionParams params;
  params.bandwidth = 0.5;
  params.min_voxels = 3;
  params.min_width = 0.05;  // 30 points fill only three rows: σ = 3.6 mm in z
  const auto x = detect_planes(map, 0, params);
  ASSERT_EQ(x.size(), 1U);
  EXPECT_NEAR(x[0].coordinate, 0.32, 1e-6);  // moments are kept in float
  EXPECT_EQ(x[0].flat_voxels, 3U);
  EXPECT_EQ(x[0].points, 160U);
  // Too few voxels for a plane.
  params.min_voxels = 4;
  EXPECT_TRUE(detect_planes(map, 0, params).empty());
}

// Two faces 75 mm apart (box B's front and back) are two planes, not one.
TEST(DetectPlanes, SeparatesTwoCloseParallelFaces) {
  VoxelMap map(0.0586);
  std::mt19937 rng(3);
  add_rect(map, 1, 2.05, {-0.45, -1.0}, {-0.08, -0.215}, 0.005, 0.003, rng);
  add_rect(map, 1, 2.125, {-0.45, -1.0}, {-0.08, -0.215}, 0.005, 0.003, rng);
  const auto y = detect_planes(map, 1);
  ASSERT_EQ(y.size(), 2U) << ::testing::PrintToString(coordinates(y));
  EXPECT_NEAR(y[0].coordinate, 2.05, 0.002);
  EXPECT_NEAR(y[1].coordinate, 2.125, 0.002);
  // Each keeps its own voxels: the two fronts end at x = −0.08 and start at −0.45.
  for (const auto& p : y) {
    EXPECT_NEAR(*plane_end(map, p, 0, +1), -0.08, 0.25 * map.edge());
    EXPECT_NEAR(*plane_end(map, p, 0, -1), -0.45, 0.25 * map.edge());
  }
}

// A plane is a connected piece, not every flat voxel at one coordinate: six face-on patches of one
// voxel each at y = 0.5 (5 mm samples over 5 cm × 5 cm, 2 mm noise), 0.3 m apart, are no plane;
// the same six side by side (a 2 × 3 voxel patch) are one at 0.5.
TEST(DetectPlanes, ScatteredFlatVoxelsAreNoPlane) {
  const auto patches = [](double spacing) {
    VoxelMap map(0.0586);
    std::mt19937 rng(5);
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 2; ++b) {
        const double x = 0.0586 * 0.1 + spacing * a;
        const double z = 0.0586 * 0.1 + spacing * b;
        add_rect(map, 1, 0.5, {x, z}, {x + 0.05, z + 0.05}, 0.005, 0.002, rng);
      }
    }
    return map;
  };
  PlaneDetectionParams params;
  params.min_width = 0.1;  // each patch alone spreads σ = 14 mm: flat by itself
  EXPECT_TRUE(detect_planes(patches(0.3), 1, params).empty());
  const auto y = detect_planes(patches(0.0586), 1, params);
  ASSERT_EQ(y.size(), 1U);
  EXPECT_NEAR(y[0].coordinate, 0.5, 0.002);
  EXPECT_EQ(y[0].flat_voxels, 6U);
}

// Matching, by hand: planes at 0.0, 0.05, 0.5 and faces at 0.0 and 0.1 (gates 0.05): 0.0 is the
// first face's, 0.05 lies exactly half-way and serves neither, so the second face is missing; the
// last face at 1.0 has the max gate 0.25 and no plane within it.
TEST(AssociateFaces, NearestPlaneWithinHalfTheGapServesOneFaceOnly) {
  std::vector<DetectedPlane> planes(3);
  planes[0].coordinate = 0.0;
  planes[1].coordinate = 0.05;
  planes[2].coordinate = 0.5;
  const auto match = associate_faces(planes, {0.0, 0.1, 1.0});
  ASSERT_EQ(match.size(), 3U);
  EXPECT_EQ(match[0], std::optional<std::size_t>(0));
  EXPECT_FALSE(match[1].has_value());
  EXPECT_FALSE(match[2].has_value());
  EXPECT_DOUBLE_EQ(face_gate({0.0, 0.1, 1.0}, 2), 0.25);
  // Moved to 0.06 the plane is nearer the second face than its gate: it serves that one only.
  planes[1].coordinate = 0.06;
  const auto moved = associate_faces(planes, {0.0, 0.1, 1.0});
  EXPECT_EQ(moved[0], std::optional<std::size_t>(0));
  EXPECT_EQ(moved[1], std::optional<std::size_t>(1));
  EXPECT_TRUE(associate_faces({}, {0.0, 0.1}) == (std::vector<std::optional<std::size_t>>{std::nullopt, std::nullopt}));
  EXPECT_TRUE(associate_faces(planes, {}).empty());
}

TEST(DetectPlanes, EmptyAndDegenerateInputs) {
  VoxelMap map(0.06);
  for (int axis = 0; axis < 3; ++axis) EXPECT_TRUE(detect_planes(map, axis).empty());
  EXPECT_THROW((void)detect_planes(map, 3), Error);
  EXPECT_THROW((void)detect_planes(map, -1), Error);
  PlaneDetectionParams bad;
  bad.bandwidth = 0.0;
  EXPECT_THROW((void)detect_planes(map, 0, bad), Error);
  // Voxels with fewer than min_points points, and misses only, are no plane.
  for (int k = 0; k < 10; ++k) {
    map.add_hit(Eigen::Vector3d(0.1 * k, 0.0, 0.0));
    map.add_hit(Eigen::Vector3d(0.1 * k + 0.01, 0.0, 0.0));
    map.add_miss(VoxelKey{k, 5, 5});
  }
  for (int axis = 0; axis < 3; ++axis) EXPECT_TRUE(detect_planes(map, axis).empty());
  // A plane with no voxels has no end; an end along the plane's own axis is an error.
  DetectedPlane none;
  none.axis = 2;
  EXPECT_FALSE(plane_end(map, none, 0, -1).has_value());
  EXPECT_THROW((void)plane_end(map, none, 2, +1), Error);
  // A region holding nothing finds nothing.
  const VoxelMap full = scene(0.25);
  PlaneDetectionParams far;
  far.region = Eigen::AlignedBox3d(Eigen::Vector3d(5, 5, 5), Eigen::Vector3d(6, 6, 6));
  EXPECT_TRUE(detect_planes(full, 2, far).empty());
}

}  // namespace
}  // namespace hmap::pvox
