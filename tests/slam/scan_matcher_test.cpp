#include "hmap/slam/scan_matcher.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "hmap/maps/mapper.hpp"
#include "hmap/sim/composites.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"
#include "hmap/slam/hmap_slam.hpp"

namespace hmap::slam {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kSensorHeight = 1.8;

/// A 40 × 30 m yard: walls around, pillars, boxes and a kiosk, so every direction is constrained.
sim::SceneBuilder yard_builder() {
  using sim::Box;
  using sim::Cylinder;
  using sim::SurfaceKind;
  sim::SceneBuilder b;
  b.add("ground", sim::make_ground({-25, -20}, {25, 20}, 0.0));
  b.add("north", sim::make_wall({-20, 15}, {20, 15}, 3.0));
  b.add("south", sim::make_wall({-20, -15}, {12, -15}, 4.0));
  b.add("west", sim::make_wall({-20, -15}, {-20, 15}, 2.5));
  b.add("east", sim::make_wall({20, -8}, {20, 15}, 3.5));
  for (int k = 0; k < 5; ++k) {
    b.add("pillar", {{Cylinder{{-12.0 + 6.0 * k, 6.0 + (k % 2) * 2.0}, 0.0, 3.0, 0.3}, SurfaceKind::kPillar}});
  }
  b.add("box1", {{Box{{4, -6, 0.6}, {1.0, 0.5, 0.6}, 0.4}, SurfaceKind::kBox}});
  b.add("box2", {{Box{{-7, -4, 1.0}, {0.6, 1.2, 1.0}, -0.3}, SurfaceKind::kBox}});
  b.add("kiosk", {{Box{{10, 4, 1.5}, {2.0, 1.5, 1.5}, 0.0}, SurfaceKind::kWall}});
  return b;
}

Params yard_params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.05;
  p.map.max_range = 25.0;
  p.slam.min_layer_height = 0.1;
  return p;
}

Pose sensor_pose(const PlanarPose& xi) { return compose(xi, Attitude{kSensorHeight, 0.0, 0.0}); }

PointCloud scan_at(const sim::Scene& scene, const PlanarPose& xi, double t, std::uint64_t seed) {
  sim::SpinningLidarParams lp = sim::SpinningLidarParams::hdl64e();
  lp.seed = seed;
  sim::SpinningLidar lidar(lp);
  return lidar.scan(scene, sensor_pose(xi), t).points_sensor;
}

/// The map of scans at `map_poses`, and a second scan at `xi1` built in its gravity-aligned frame.
struct TwoScans {
  HMap map;
  ScanHVoxels scan_level;
};

TwoScans two_scans(const sim::Scene& scene, const Params& p, const std::vector<PlanarPose>& map_poses,
                   const PlanarPose& xi1, double t1 = 0.0) {
  Mapper mapper(p);
  std::uint64_t seed = 1;
  for (const PlanarPose& xi0 : map_poses) mapper.integrate(scan_at(scene, xi0, 0.0, seed++), sensor_pose(xi0));
  ScanHVoxelizer level(p.map);
  TwoScans out{std::move(mapper.map()), {}};
  const PointCloud second = scan_at(scene, xi1, t1, 2);
  level.build(second, compose(PlanarPose{}, Attitude{kSensorHeight, 0.0, 0.0}), out.scan_level);
  return out;
}

double yaw_error(double a, double b) { return std::abs(std::remainder(a - b, 2.0 * std::numbers::pi)); }

TEST(ScanMatcher, RecoversAKnownPlanarTransform) {
  const sim::Scene scene = yard_builder().build();
  const Params p = yard_params();
  const PlanarPose truth{0.08, -0.06, 1.0 * kDeg};
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, truth);
  ScanMatcher matcher(p);
  const MatchResult r = matcher.match(s.scan_level, s.map, PlanarPose{});
  EXPECT_TRUE(r.converged);
  EXPECT_FALSE(r.degenerate);
  EXPECT_GT(r.hvoxels_used, 1000U);
  EXPECT_LT(r.final_cost, r.initial_cost);
  EXPECT_NEAR(r.pose.x, truth.x, 0.02);
  EXPECT_NEAR(r.pose.y, truth.y, 0.02);
  EXPECT_LT(yaw_error(r.pose.yaw, truth.yaw), 0.2 * kDeg);
  // The Hessian is symmetric positive definite here.
  EXPECT_TRUE(r.hessian.isApprox(r.hessian.transpose()));
  EXPECT_GT(r.eigenvalues(0), 0.0);
}

bool recovered(const MatchResult& r, const PlanarPose& truth) {
  return std::hypot(r.pose.x - truth.x, r.pose.y - truth.y) < 0.02 && yaw_error(r.pose.yaw, truth.yaw) < 0.2 * kDeg;
}

TEST(ScanMatcher, ConvergenceBasin) {
  // Measured at 0.05 m cells, Gauss-Newton alone (no coarse search), HDL-64 in the yard: every
  // guess 0.1 m off (8 directions) or 2° off converges to the truth; 0.2 m: 5 of 8; 0.4 m: none.
  // The coarse search (±0.5 m, ±0.5 rad) brings a guess 0.4 m and 5° off back.
  const sim::Scene scene = yard_builder().build();
  Params p = yard_params();
  p.slam.coarse_trigger_ratio = 0.0;
  const PlanarPose truth{0.5, 0.3, 2.0 * kDeg};
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, truth);
  ScanMatcher matcher(p);
  auto successes = [&](double offset, double dyaw) {
    int ok = 0;
    for (int k = 0; k < 8; ++k) {
      const double dir = k * std::numbers::pi / 4.0;
      const PlanarPose guess{truth.x + offset * std::cos(dir), truth.y + offset * std::sin(dir),
                             truth.yaw + (k % 2 == 0 ? dyaw : -dyaw)};
      ok += recovered(matcher.match(s.scan_level, s.map, guess), truth) ? 1 : 0;
    }
    return ok;
  };
  EXPECT_GE(successes(0.1, 0.0), 7);
  EXPECT_EQ(successes(0.0, 2.0 * kDeg), 8);
  EXPECT_GE(successes(0.2, 0.0), 4);
  EXPECT_EQ(successes(0.4, 0.0), 0);

  const PlanarPose far{truth.x - 0.4, truth.y + 0.1, truth.yaw + 5.0 * kDeg};
  EXPECT_FALSE(recovered(matcher.match(s.scan_level, s.map, far), truth));
  p.slam.coarse_trigger_ratio = 0.85;
  ScanMatcher with_search(p);
  (void)with_search.match(s.scan_level, s.map, truth);  // a good match sets the reference score
  const MatchResult found = with_search.match(s.scan_level, s.map, far);
  EXPECT_TRUE(found.coarse_search);
  EXPECT_TRUE(recovered(found, truth)) << found.pose.x << " " << found.pose.y << " " << found.pose.yaw;
}

TEST(ScanMatcher, FeaturelessCorridorIsDegenerate) {
  // Two parallel walls along x, far longer than the sensor's reach: nothing fixes x.
  sim::SceneBuilder b;
  // No floor and walls lower than the sensor: the rings' pattern on a floor would be a feature.
  b.add("left", sim::make_wall({-200, 2.0}, {200, 2.0}, 1.5));
  b.add("right", sim::make_wall({-200, -2.0}, {200, -2.0}, 1.5));
  const sim::Scene scene = b.build();
  const Params p = yard_params();
  const PlanarPose truth{0.4, 0.05, 1.0 * kDeg};
  // The map reaches well beyond the second scan, so that the map's own end is no feature.
  TwoScans s = two_scans(scene, p, {{-12, 0, 0}, {0, 0, 0}, {12, 0, 0}}, truth);
  ScanMatcher matcher(p);
  const PlanarPose guess{0.1, 0.0, 0.0};
  const MatchResult r = matcher.match(s.scan_level, s.map, guess);
  EXPECT_TRUE(r.degenerate);
  EXPECT_LT(r.curvature.minCoeff(), p.slam.degeneracy_ratio * r.curvature.maxCoeff());
  // x stays at the guess (the prediction carries it); y and yaw are still found.
  EXPECT_NEAR(r.pose.x, guess.x, 0.05);
  EXPECT_NEAR(r.pose.y, truth.y, 0.03);
  EXPECT_LT(yaw_error(r.pose.yaw, truth.yaw), 0.3 * kDeg);
  // The yard is not degenerate (checked above); neither is an empty scan silently accepted.
  ScanHVoxels empty;
  const MatchResult none = matcher.match(empty, s.map, guess);
  EXPECT_TRUE(none.degenerate);
  EXPECT_FALSE(none.converged);
  EXPECT_TRUE(none.skipped);
  EXPECT_EQ(none.hvoxels_used, 0U);
}

TEST(ScanMatcher, MovingCarDoesNotPullThePose) {
  // A car 4 m from the sensor in the mapped scan drives 3 m along +x before the second scan: the
  // match lands where it lands without the car (to 5 mm and 0.05°), and on the truth.
  sim::SceneBuilder b = yard_builder();
  b.add_moving("car", sim::make_car(), sim::MotionPath({{0.0, {2.0, 4.0, 0.0}, 0.0}, {1.0, {5.0, 4.0, 0.0}, 0.0}}));
  const sim::Scene with_car = b.build();
  const sim::Scene without_car = yard_builder().build();
  const Params p = yard_params();
  const PlanarPose truth{0.08, 0.05, 0.5 * kDeg};
  TwoScans s = two_scans(with_car, p, {PlanarPose{}}, truth, /*t1=*/1.0);
  TwoScans still = two_scans(without_car, p, {PlanarPose{}}, truth, /*t1=*/1.0);
  ASSERT_NE(s.scan_level.hvoxels.size(), still.scan_level.hvoxels.size());  // the car was seen
  ScanMatcher matcher(p);
  const MatchResult r = matcher.match(s.scan_level, s.map, PlanarPose{});
  const MatchResult r0 = matcher.match(still.scan_level, still.map, PlanarPose{});
  EXPECT_NEAR(r.pose.x, r0.pose.x, 0.005);
  EXPECT_NEAR(r.pose.y, r0.pose.y, 0.005);
  EXPECT_LT(yaw_error(r.pose.yaw, r0.pose.yaw), 0.05 * kDeg);
  EXPECT_NEAR(r.pose.x, truth.x, 0.02);
  EXPECT_NEAR(r.pose.y, truth.y, 0.02);
  EXPECT_LT(yaw_error(r.pose.yaw, truth.yaw), 0.3 * kDeg);
}

/// A scan of `posts` thin vertical posts 1.5 m tall on a circle of radius 6 m around the sensor,
/// 15 points each: one tall HVoxel per post.
ScanHVoxels posts_scan(const Params& p, int posts) {
  PointCloud points;
  for (int k = 0; k < posts; ++k) {
    const double a = 2.0 * std::numbers::pi * (k + 0.5) / posts;
    for (int z = 0; z < 15; ++z) {
      points.emplace_back(static_cast<float>(6.0 * std::cos(a)), static_cast<float>(6.0 * std::sin(a)),
                          static_cast<float>(-1.5 + 0.1 * z));
    }
  }
  ScanHVoxels scan_level;
  ScanHVoxelizer(p.map).build(points, compose(PlanarPose{}, Attitude{kSensorHeight, 0.0, 0.0}), scan_level);
  return scan_level;
}

TEST(ScanMatcher, TooFewHVoxelsKeepTheGuess) {
  // A scan that shows a handful of HVoxels (a pedestrian, a kerb) is not matched: the guess is
  // kept and the result says so. One HVoxel more than the minimum and it is matched again.
  const sim::Scene scene = yard_builder().build();
  const Params p = yard_params();
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, {});
  const auto minimum = static_cast<int>(ScanMatcher::kMinHVoxels);
  const ScanHVoxels few = posts_scan(p, minimum - 1);
  ASSERT_EQ(few.hvoxels.size(), ScanMatcher::kMinHVoxels - 1);
  ScanMatcher matcher(p);
  const PlanarPose guess{0.3, -0.2, 0.05};
  const MatchResult r = matcher.match(few, s.map, guess);
  EXPECT_TRUE(r.skipped);
  EXPECT_FALSE(r.converged);
  EXPECT_TRUE(r.degenerate);
  EXPECT_EQ(r.hvoxels_used, ScanMatcher::kMinHVoxels - 1);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_DOUBLE_EQ(r.pose.x, guess.x);
  EXPECT_DOUBLE_EQ(r.pose.y, guess.y);
  EXPECT_DOUBLE_EQ(r.pose.yaw, guess.yaw);

  const MatchResult enough = matcher.match(posts_scan(p, minimum), s.map, guess);
  EXPECT_FALSE(enough.skipped);
  EXPECT_EQ(enough.hvoxels_used, ScanMatcher::kMinHVoxels);
  EXPECT_GT(enough.iterations, 0);

  // min_match_height counts: the same posts are too short for a 2 m minimum.
  Params tall = p;
  tall.slam.min_match_height = 2.0;
  ScanMatcher tall_matcher(tall);
  const MatchResult filtered = tall_matcher.match(posts_scan(p, 2 * minimum), s.map, guess);
  EXPECT_TRUE(filtered.skipped);
  EXPECT_EQ(filtered.hvoxels_used, 0U);
}

TEST(ScanMatcher, EmptyMapGivesTheGuessBack) {
  const sim::Scene scene = yard_builder().build();
  const Params p = yard_params();
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, {});
  const HMap empty(p);
  ScanMatcher matcher(p);
  const PlanarPose guess{1.0, 2.0, 0.1};
  const MatchResult r = matcher.match(s.scan_level, empty, guess);
  EXPECT_NEAR(r.pose.x, guess.x, 1e-9);
  EXPECT_NEAR(r.pose.y, guess.y, 1e-9);
  EXPECT_NEAR(r.pose.yaw, guess.yaw, 1e-9);
  EXPECT_TRUE(r.degenerate);
  EXPECT_DOUBLE_EQ(r.score, 0.0);
}

TEST(ScanMatcher, ThinFallbackOnBareGroundKeepsTheGuess) {
  // Bare flat ground and nothing taller (the parking side road's empty end), a VLP-16 driving along
  // x, no odometry: the match falls back on the thin HVoxels. The ground is the same everywhere, so
  // only the edge of what the map has seen could move the pose, and it pulled the scan back onto
  // the seen part. Only HVoxels where the map is known all around take part: the guess stands.
  // Without that rule the match moved the pose 0.14 m in x and in y (measured).
  sim::SceneBuilder b;
  b.add("ground", sim::make_ground({-100, -100}, {100, 100}, 0.0));
  const sim::Scene scene = b.build();
  Params p = outdoor_preset();
  p.map.max_range = 25.0;
  sim::SpinningLidar lidar(sim::SpinningLidarParams::vlp16());
  Mapper mapper(p);
  for (const double x : {-3.0, -1.5, 0.0}) {
    const Pose T = sensor_pose(PlanarPose{x, 0.0, 0.0});
    mapper.integrate(lidar.scan(scene, T, 0.0).points_sensor, T);
  }
  const PlanarPose truth{1.5, 0.0, 0.0};
  ScanHVoxels level;
  ScanHVoxelizer(p.map).build(lidar.scan(scene, sensor_pose(truth), 0.1).points_sensor,
                              compose(PlanarPose{}, Attitude{kSensorHeight, 0.0, 0.0}), level);
  ScanMatcher matcher(p);
  const MatchResult r = matcher.match(level, mapper.map(), truth, CoarseSearch::kWhenFailed, std::nullopt,
                                      /*thin_fallback=*/true);
  // A VLP-16's sparse rings leave few cells known all around: the match is skipped or stays put.
  EXPECT_NEAR(r.pose.x, truth.x, 0.05);
  EXPECT_NEAR(r.pose.y, truth.y, 0.05);
  EXPECT_LT(yaw_error(r.pose.yaw, truth.yaw), 0.2 * kDeg);
}

}  // namespace
}  // namespace hmap::slam
