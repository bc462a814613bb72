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

TEST(ScanMatcher, RecoversAKnownPlanarTransformAtAnyHeading) {
  // The same small transform as above, with the sensor heading 90°, 180° and −120° in the map: the
  // yaw column of the Jacobian (∂S/∂φ) has its sin φ terms in play, which vanish near φ = 0.
  const sim::Scene scene = yard_builder().build();
  const Params p = yard_params();
  for (const double heading : {90.0 * kDeg, 180.0 * kDeg, -120.0 * kDeg}) {
    const PlanarPose first{0.0, 0.0, heading};
    const PlanarPose truth{0.08, -0.06, heading + 1.0 * kDeg};
    TwoScans s = two_scans(scene, p, {first}, truth);
    ScanMatcher matcher(p);
    const MatchResult r = matcher.match(s.scan_level, s.map, first);
    EXPECT_TRUE(r.converged) << heading / kDeg;
    EXPECT_FALSE(r.coarse_search) << heading / kDeg;  // Gauss-Newton found it from the guess
    EXPECT_NEAR(r.pose.x, truth.x, 0.02) << heading / kDeg;
    EXPECT_NEAR(r.pose.y, truth.y, 0.02) << heading / kDeg;
    EXPECT_LT(yaw_error(r.pose.yaw, truth.yaw), 0.2 * kDeg) << heading / kDeg;
  }
}

// eq. (6)'s v is the HVoxel's plan centroid when the scan carries them (slam.hvoxel_centroids):
// every centroid moved by 3 cm in x moves the matched pose back by as much, and none matches at the
// cells' centres as the paper has it.
TEST(ScanMatcher, MatchesTheScanAtItsHVoxelsCentroids) {
  const sim::Scene scene = yard_builder().build();
  const Params p = yard_params();
  const PlanarPose truth{0.08, -0.06, 1.0 * kDeg};
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, truth);
  ASSERT_TRUE(s.scan_level.centroids.empty());
  ScanMatcher matcher(p);
  const MatchResult at_centres = matcher.match(s.scan_level, s.map, PlanarPose{});
  ScanHVoxelizer level(p.map);
  level.keep_centroids(true);
  level.build(scan_at(scene, truth, 0.0, 2), compose(PlanarPose{}, Attitude{kSensorHeight, 0.0, 0.0}), s.scan_level);
  ASSERT_EQ(s.scan_level.centroids.size(), s.scan_level.hvoxels.size());
  const MatchResult at_centroids = matcher.match(s.scan_level, s.map, PlanarPose{});
  EXPECT_TRUE(at_centroids.converged);
  EXPECT_NEAR(at_centroids.pose.x, truth.x, 0.01);
  EXPECT_NEAR(at_centroids.pose.y, truth.y, 0.01);
  EXPECT_LT(yaw_error(at_centroids.pose.yaw, truth.yaw), 0.1 * kDeg);
  EXPECT_NE(at_centroids.pose.x, at_centres.pose.x);
  for (Eigen::Vector2f& c : s.scan_level.centroids) c.x() += 0.03F;
  const MatchResult moved = matcher.match(s.scan_level, s.map, PlanarPose{});
  EXPECT_NEAR(moved.pose.x, at_centroids.pose.x - 0.03, 0.003);
  EXPECT_NEAR(moved.pose.y, at_centroids.pose.y, 0.003);
  EXPECT_LT(yaw_error(moved.pose.yaw, at_centroids.pose.yaw), 0.02 * kDeg);
}

// The map read at its cells' centroids (slam.hvoxel_centroids 2). Every map column's centroid
// put at its cell's centre changes nothing, bit for bit; put 1 cm east of it, the map reads as if
// 1 cm east, and the scan is found 1 cm farther east.
TEST(ScanMatcher, ReadsTheMapAtItsCellsCentroids) {
  const sim::Scene scene = yard_builder().build();
  const Params p = yard_params();
  const double cell = p.map.cell_size;
  const PlanarPose truth{0.08, -0.06, 1.0 * kDeg};
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, truth);
  CellCentroids centred(cell);
  CellCentroids east(cell);
  s.map.for_each_column([&](const CellKey& k, const auto&) {
    centred.add((k.i + 0.5) * cell, (k.j + 0.5) * cell, 1.0);
    east.add((k.i + 0.5) * cell + 0.01, (k.j + 0.5) * cell, 1.0);
  });
  ASSERT_GT(east.size(), 1000U);
  ScanMatcher matcher(p);
  const MatchResult none = matcher.match(s.scan_level, s.map, PlanarPose{});
  matcher.set_map_centroids(&centred);
  const MatchResult same = matcher.match(s.scan_level, s.map, PlanarPose{});
  EXPECT_EQ(same.pose.x, none.pose.x);
  EXPECT_EQ(same.pose.y, none.pose.y);
  EXPECT_EQ(same.pose.yaw, none.pose.yaw);
  matcher.set_map_centroids(&east);
  const MatchResult moved = matcher.match(s.scan_level, s.map, PlanarPose{});
  EXPECT_NEAR(moved.pose.x, none.pose.x + 0.01, 0.002);
  EXPECT_NEAR(moved.pose.y, none.pose.y, 0.002);
  EXPECT_LT(yaw_error(moved.pose.yaw, none.pose.yaw), 0.02 * kDeg);
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
  EXPECT_FALSE(found.wide_search);  // found within the usual window
  EXPECT_TRUE(recovered(found, truth)) << found.pose.x << " " << found.pose.y << " " << found.pose.yaw;
}

TEST(ScanMatcher, ALostMatchSearchesEveryHeading) {
  // The sensor turned 70° and moved 0.7 m more than predicted (a jerk, a dropped scan): outside the
  // coarse search's ±0.5 m, ±0.5 rad. Its best there fits the map less than half as well as the
  // last match, so every heading is searched within ±1 m, and the truth is found.
  const sim::Scene scene = yard_builder().build();
  Params p = yard_params();
  p.map.cell_size = 0.1;  // the wide search's grid is then 11 × 11 positions, not 21 × 21
  const PlanarPose truth{0.5, 0.3, 70.0 * kDeg};
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, truth);
  const PlanarPose guess{-0.1, -0.1, 0.0};
  // No match before it: nothing to compare the fit with, so nothing is taken for lost.
  ScanMatcher fresh(p);
  fresh.search_when_lost(true);
  const MatchResult blind = fresh.match(s.scan_level, s.map, guess);
  EXPECT_FALSE(blind.wide_search);
  EXPECT_FALSE(recovered(blind, truth));
  ScanMatcher off(p);  // not asked to search when lost (a map registration's matcher)
  (void)off.match(s.scan_level, s.map, truth);
  const MatchResult stays = off.match(s.scan_level, s.map, guess);
  EXPECT_FALSE(stays.wide_search);
  EXPECT_FALSE(recovered(stays, truth));
  ScanMatcher matcher(p);
  matcher.search_when_lost(true);  // as HmapSlam's
  const MatchResult good = matcher.match(s.scan_level, s.map, truth);  // the reference fit
  EXPECT_FALSE(good.wide_search);
  const MatchResult lost = matcher.match(s.scan_level, s.map, guess);
  EXPECT_TRUE(lost.coarse_search);
  EXPECT_TRUE(lost.wide_search);
  EXPECT_TRUE(recovered(lost, truth)) << lost.pose.x << " " << lost.pose.y << " " << lost.pose.yaw / kDeg;
  EXPECT_GT(lost.score, 0.9 * good.score);
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

/// A VLP-16 driving along x in `scene`: the map of its scans at `map_x` (heading 0), and its scan at
/// `truth` in that scan's gravity-aligned frame.
TwoScans vlp16_drive(const sim::Scene& scene, const Params& p, std::initializer_list<double> map_x,
                     const PlanarPose& truth) {
  sim::SpinningLidar lidar(sim::SpinningLidarParams::vlp16());
  Mapper mapper(p);
  for (const double x : map_x) {
    const Pose T = sensor_pose(PlanarPose{x, 0.0, 0.0});
    mapper.integrate(lidar.scan(scene, T, 0.0).points_sensor, T);
  }
  TwoScans out{std::move(mapper.map()), {}};
  ScanHVoxelizer(p.map).build(lidar.scan(scene, sensor_pose(truth), 0.1).points_sensor,
                              compose(PlanarPose{}, Attitude{kSensorHeight, 0.0, 0.0}), out.scan_level);
  return out;
}

/// A road between two 12 cm kerbs, pavements beyond, and nothing taller (the parking side road's
/// empty end).
sim::Scene kerbed_road() {
  using sim::Box;
  using sim::SurfaceKind;
  sim::SceneBuilder b;
  b.add("road", sim::make_ground({-80, -3.5}, {80, 3.5}, 0.0));
  b.add("kerb", {{Box{{0.0, 3.6, -0.04}, {80.0, 0.1, 0.16}, 0.0}, SurfaceKind::kCurb}});
  b.add("kerb", {{Box{{0.0, -3.6, -0.04}, {80.0, 0.1, 0.16}, 0.0}, SurfaceKind::kCurb}});
  b.add("walk", sim::make_ground({-80, 3.7}, {80, 12}, 0.12));
  b.add("walk", sim::make_ground({-80, -12}, {80, -3.7}, 0.12));
  return b.build();
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
  const PlanarPose truth{1.5, 0.0, 0.0};
  const TwoScans s = vlp16_drive(scene, p, {-3.0, -1.5, 0.0}, truth);
  ScanMatcher matcher(p);
  const MatchResult r = matcher.match(s.scan_level, s.map, truth, CoarseSearch::kWhenFailed, std::nullopt,
                                      /*thin_fallback=*/ThinFallback::kFull);
  // A VLP-16's sparse rings leave few cells known all around: the match is skipped or stays put.
  EXPECT_NEAR(r.pose.x, truth.x, 0.05);
  EXPECT_NEAR(r.pose.y, truth.y, 0.05);
  EXPECT_LT(yaw_error(r.pose.yaw, truth.yaw), 0.2 * kDeg);
}

// The thin fallback matches at the cells' centres on both sides, though the scan has its
// HVoxels' centroids and the map has centroids (slam.hvoxel_centroids 2): the map keeps centroids
// for the tall HVoxels only, so ground rings at their points' centroids met cells at their centres.
// On the parking route's blind stretch without odometry that ran away forward, the constant
// velocity feeding it on (docs/SLAM.md, session 30). The match is the one without any centroids,
// bit for bit; with them taken (the map's 3 cm east of every centre) it would move.
TEST(ScanMatcher, ThinFallbackMatchesAtTheCellsCentres) {
  const sim::Scene scene = kerbed_road();
  const Params p = outdoor_preset();
  const double cell = p.map.cell_size;
  const PlanarPose truth{0.4, 0.0, 0.0};
  TwoScans s = vlp16_drive(scene, p, {-1.2, -0.8, -0.4, 0.0}, truth);
  // The scan again, from the same points: without its centroids and with them.
  sim::SpinningLidar lidar(sim::SpinningLidarParams::vlp16());
  const PointCloud points = lidar.scan(scene, sensor_pose(truth), 0.1).points_sensor;
  const Pose level_frame = compose(PlanarPose{}, Attitude{kSensorHeight, 0.0, 0.0});
  ScanHVoxels at_centres;
  ScanHVoxelizer(p.map).build(points, level_frame, at_centres);
  ScanHVoxelizer level(p.map);
  level.keep_centroids(true);
  ScanHVoxels with_centroids;
  level.build(points, level_frame, with_centroids);
  ASSERT_EQ(with_centroids.hvoxels, at_centres.hvoxels);
  ASSERT_EQ(with_centroids.centroids.size(), with_centroids.hvoxels.size());
  const PlanarPose guess{0.45, 0.03, 0.5 * kDeg};
  ScanMatcher plain(p);
  const MatchResult without = plain.match(at_centres, s.map, guess, CoarseSearch::kWhenFailed, std::nullopt,
                                          ThinFallback::kFull);
  ASSERT_FALSE(without.skipped);
  ASSERT_GE(without.hvoxels_used, ScanMatcher::kMinHVoxels);
  ASSERT_NE(without.pose.yaw, guess.yaw);  // the thin HVoxels moved it
  // The map's centroids put 3 cm east of every centre.
  CellCentroids east(cell);
  s.map.for_each_column([&](const CellKey& k, const auto&) { east.add((k.i + 0.5) * cell + 0.03, (k.j + 0.5) * cell, 1.0); });
  ScanMatcher centroids(p);
  centroids.set_map_centroids(&east);
  const MatchResult thin = centroids.match(with_centroids, s.map, guess, CoarseSearch::kWhenFailed, std::nullopt,
                                           ThinFallback::kFull);
  EXPECT_EQ(thin.pose.x, without.pose.x);
  EXPECT_EQ(thin.pose.y, without.pose.y);
  EXPECT_EQ(thin.pose.yaw, without.pose.yaw);
  EXPECT_EQ(thin.iterations, without.iterations);
}

TEST(ScanMatcher, ThinHeadingMatchTurnsByTheKerbsAndKeepsTheOdometrysPosition) {
  // A road between two 12 cm kerbs and nothing taller (the parking side road's empty end), a VLP-16
  // driving along x at 0.4 m per scan, with odometry 5 cm ahead and 1.5 deg off after a blind stretch
  // (its prior's sigma grown to 0.03 rad). Fewer than kMinHVoxels tall HVoxels: with
  // ThinFallback::kNone the odometry's pose is kept as it is; with kHeading the thin HVoxels turn
  // the yaw back (the kerbs run along x) and x, y stay the odometry's exactly: translated, the
  // rings the map was laid with would pull the pose back toward the last scan.
  const sim::Scene scene = kerbed_road();
  const Params p = outdoor_preset();  // 0.25 m cells, 25 m range
  const PlanarPose truth{0.4, 0.0, 0.0};
  const TwoScans s = vlp16_drive(scene, p, {-1.2, -0.8, -0.4, 0.0}, truth);
  const PlanarPose odometry{0.45, 0.0, 1.5 * kDeg};
  const MotionPrior prior = MotionPrior::from_sigmas(odometry, 0.05, 0.03);

  ScanMatcher keep(p);
  const MatchResult kept = keep.match(s.scan_level, s.map, odometry, CoarseSearch::kWhenFailed, std::nullopt,
                                      ThinFallback::kNone, prior);
  EXPECT_TRUE(kept.skipped);
  EXPECT_FALSE(kept.heading_only);
  EXPECT_DOUBLE_EQ(kept.pose.yaw, odometry.yaw);

  ScanMatcher heading(p);
  const MatchResult turned = heading.match(s.scan_level, s.map, odometry, CoarseSearch::kWhenFailed, std::nullopt,
                                           ThinFallback::kHeading, prior);
  EXPECT_FALSE(turned.skipped);
  EXPECT_TRUE(turned.heading_only);
  EXPECT_GE(turned.hvoxels_used, ScanMatcher::kMinHVoxels);
  // From 1.5 deg to under 0.5 (0.44 measured; the kerbs are seen within a few metres only, where
  // the map is known all around, and a 0.4 deg turn moves them 3 cm there, an eighth of a cell).
  EXPECT_LT(yaw_error(turned.pose.yaw, truth.yaw), 0.5 * kDeg);
  EXPECT_DOUBLE_EQ(turned.pose.x, odometry.x);
  EXPECT_DOUBLE_EQ(turned.pose.y, odometry.y);
  // What the scan told is the yaw alone: x and y are reported unobservable, and the covariance
  // keeps the odometry's sigma there (0.05 m) while the yaw's shrinks below the prior's 0.03 rad.
  EXPECT_TRUE(turned.degenerate);
  EXPECT_FALSE(turned.observable[0]);
  EXPECT_FALSE(turned.observable[1]);
  EXPECT_NEAR(std::sqrt(turned.covariance(0, 0)), 0.05, 1e-3);
  EXPECT_NEAR(std::sqrt(turned.covariance(1, 1)), 0.05, 1e-3);
  EXPECT_LT(std::sqrt(turned.covariance(2, 2)), 0.5 * 0.03);
}

/// Vertical posts 2 m tall, 21 points each (every 0.1 m), at the given (x, y) around a sensor 1.8 m
/// above the ground, in its gravity-aligned frame: one tall HVoxel per post.
PointCloud posts_at(const std::vector<Eigen::Vector2d>& xy) {
  PointCloud points;
  for (const Eigen::Vector2d& q : xy) {
    for (int z = 0; z <= 20; ++z) {
      points.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(-kSensorHeight + 0.1 * z));
    }
  }
  return points;
}

TEST(ScanMatcher, OdometryPriorHoldsWhatOneMovedPostWouldPull) {
  // A corridor of two walls along x (nothing in them fixes x) and one post, which moved 0.5 m along
  // +x between the map and the scan (a parked car that left). The sensor stood still. Without a
  // prior the post is all that fixes x, and the coarse search aligns it: the pose jumps 0.5 m.
  // With the odometry's prior (σ 2 cm, the default at rest) one HVoxel cannot pay for a 25σ jump:
  // the prior's cost there is s²·(0.5/0.02)² ≥ 0.01·625 = 6.25 (s² at least 0.01), the post's whole
  // residual at most 1.
  Params p = outdoor_preset();  // 0.25 m cells
  std::vector<Eigen::Vector2d> map_xy;
  std::vector<Eigen::Vector2d> scan_xy;
  for (int i = -60; i < 60; ++i) {  // the map's walls reach 5 m farther each way than the scan's
    const double x = (i + 0.5) * 0.25;
    for (const double y : {2.125, -2.125}) {
      map_xy.emplace_back(x, y);
      if (i >= -40 && i < 40) scan_xy.emplace_back(x, y);
    }
  }
  map_xy.emplace_back(3.125, 0.875);
  scan_xy.emplace_back(3.625, 0.875);
  Mapper mapper(p);
  (void)mapper.integrate(posts_at(map_xy), sensor_pose({}));
  ScanHVoxels scan_level;
  ScanHVoxelizer(p.map).build(posts_at(scan_xy), compose(PlanarPose{}, Attitude{kSensorHeight, 0.0, 0.0}), scan_level);
  ASSERT_EQ(scan_level.hvoxels.size(), scan_xy.size());

  ScanMatcher free_matcher(p);
  const MatchResult pulled = free_matcher.match(scan_level, mapper.map(), PlanarPose{}, CoarseSearch::kAlways);
  EXPECT_NEAR(pulled.pose.x, -0.5, 0.1);  // the post aligned: the test's premise
  EXPECT_DOUBLE_EQ(pulled.prior_cost, 0.0);

  ScanMatcher matcher(p);
  const MotionPrior still = MotionPrior::from_sigmas(PlanarPose{}, 0.02, 0.005);
  const MatchResult held = matcher.match(scan_level, mapper.map(), PlanarPose{}, CoarseSearch::kAlways, std::nullopt,
                                         ThinFallback::kNone, still);
  EXPECT_TRUE(held.coarse_search);
  EXPECT_NEAR(held.pose.x, 0.0, 0.05);
  EXPECT_NEAR(held.pose.y, 0.0, 0.02);
  EXPECT_LT(yaw_error(held.pose.yaw, 0.0), 0.1 * kDeg);
  // The scan's own information is reported, not the prior's: x is still the unobservable axis.
  EXPECT_TRUE(held.degenerate);
  EXPECT_FALSE(held.observable[0]);
}

TEST(ScanMatcher, OdometryPriorDoesNotHoldAWellConstrainedMatch) {
  // The yard fixes every direction with a thousand HVoxels: odometry 6 cm and 0.3° off (about 3σ of
  // its σ = 2 cm, 0.29°) ends on the truth as without the prior, within 1 cm and 0.05°.
  const sim::Scene scene = yard_builder().build();
  const Params p = yard_params();
  const PlanarPose truth{0.08, -0.06, 1.0 * kDeg};
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, truth);
  const PlanarPose odometry{truth.x + 0.05, truth.y - 0.035, truth.yaw + 0.3 * kDeg};
  ScanMatcher free_matcher(p);
  const MatchResult r0 = free_matcher.match(s.scan_level, s.map, odometry);
  ScanMatcher matcher(p);
  const MatchResult r = matcher.match(s.scan_level, s.map, odometry, CoarseSearch::kWhenFailed, std::nullopt, ThinFallback::kNone,
                                      MotionPrior::from_sigmas(odometry, 0.02, 0.005));
  EXPECT_NEAR(r.pose.x, truth.x, 0.02);
  EXPECT_NEAR(r.pose.y, truth.y, 0.02);
  EXPECT_LT(yaw_error(r.pose.yaw, truth.yaw), 0.2 * kDeg);
  EXPECT_NEAR(r.pose.x, r0.pose.x, 0.01);
  EXPECT_NEAR(r.pose.y, r0.pose.y, 0.01);
  EXPECT_LT(yaw_error(r.pose.yaw, r0.pose.yaw), 0.05 * kDeg);
  EXPECT_GT(r.prior_cost, 0.0);
  EXPECT_FALSE(r.degenerate);
}

TEST(ScanMatcher, PredictionIsKeptWhereTheCoarseSearchMovesAlongWhatTheScanDoesNotConstrain) {
  // The corridor of the test above with its one post moved 0.5 m along +x, but no odometry: the
  // guess is constant velocity (the truth here). The match scores under the reference set by the
  // unchanged scan, so the coarse search runs. Its best pose aligns the post: x jumps by −0.5 m for
  // one HVoxel's gain, while as long a move along y (the walls) costs far more. kWhenFailed takes
  // the jump; kWhenFailedKeepPrediction keeps the minimum found from the guess.
  Params p = outdoor_preset();  // 0.25 m cells
  p.slam.coarse_trigger_ratio = 1.0;  // any score under the reference's searches
  std::vector<Eigen::Vector2d> map_xy;
  std::vector<Eigen::Vector2d> scan_xy;
  for (int i = -60; i < 60; ++i) {
    const double x = (i + 0.5) * 0.25;
    for (const double y : {2.125, -2.125}) {
      map_xy.emplace_back(x, y);
      if (i >= -40 && i < 40) scan_xy.emplace_back(x, y);
    }
  }
  std::vector<Eigen::Vector2d> unchanged_xy = scan_xy;
  map_xy.emplace_back(3.125, 0.875);
  unchanged_xy.emplace_back(3.125, 0.875);
  scan_xy.emplace_back(3.625, 0.875);
  Mapper mapper(p);
  (void)mapper.integrate(posts_at(map_xy), sensor_pose({}));
  const Pose level = compose(PlanarPose{}, Attitude{kSensorHeight, 0.0, 0.0});
  ScanHVoxels unchanged;
  ScanHVoxelizer(p.map).build(posts_at(unchanged_xy), level, unchanged);
  ScanHVoxels moved;
  ScanHVoxelizer(p.map).build(posts_at(scan_xy), level, moved);

  const auto after_reference = [&](CoarseSearch mode) {
    ScanMatcher matcher(p);
    const MatchResult reference = matcher.match(unchanged, mapper.map(), PlanarPose{});
    EXPECT_FALSE(reference.coarse_search);
    return matcher.match(moved, mapper.map(), PlanarPose{}, mode);
  };
  const MatchResult jumped = after_reference(CoarseSearch::kWhenFailed);
  EXPECT_TRUE(jumped.coarse_search);
  EXPECT_FALSE(jumped.coarse_rejected);
  EXPECT_NEAR(jumped.pose.x, -0.5, 0.1);  // the premise: the lower cost is the jump

  const MatchResult kept = after_reference(CoarseSearch::kWhenFailedKeepPrediction);
  EXPECT_TRUE(kept.coarse_search);
  EXPECT_TRUE(kept.coarse_rejected);
  EXPECT_NEAR(kept.pose.x, 0.0, 0.05);
  EXPECT_NEAR(kept.pose.y, 0.0, 0.02);
  EXPECT_LT(yaw_error(kept.pose.yaw, 0.0), 0.1 * kDeg);
  EXPECT_GT(kept.final_cost, jumped.final_cost);  // kept although it costs more
  EXPECT_FALSE(kept.observable[0]);               // x is what the scan does not constrain
}

TEST(ScanMatcher, PredictionGivesWayToACoarseSearchTheWholeScanSupports) {
  // The yard constrains every direction: a guess 0.4 m and 5° off (outside Gauss-Newton's basin)
  // is corrected by the coarse search in kWhenFailedKeepPrediction as in kWhenFailed.
  const sim::Scene scene = yard_builder().build();
  const Params p = yard_params();
  const PlanarPose truth{0.5, 0.3, 2.0 * kDeg};
  TwoScans s = two_scans(scene, p, {PlanarPose{}}, truth);
  const PlanarPose far{truth.x - 0.4, truth.y + 0.1, truth.yaw + 5.0 * kDeg};
  for (const CoarseSearch mode : {CoarseSearch::kWhenFailed, CoarseSearch::kWhenFailedKeepPrediction}) {
    ScanMatcher matcher(p);
    (void)matcher.match(s.scan_level, s.map, truth);  // a good match sets the reference score
    const MatchResult found = matcher.match(s.scan_level, s.map, far, mode);
    EXPECT_TRUE(found.coarse_search);
    EXPECT_FALSE(found.coarse_rejected);
    EXPECT_TRUE(recovered(found, truth)) << found.pose.x << " " << found.pose.y << " " << found.pose.yaw;
  }
}

}  // namespace
}  // namespace hmap::slam
