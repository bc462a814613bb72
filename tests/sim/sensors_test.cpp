#include "hmap/sim/sensors.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <set>

#include "hmap/core/error.hpp"
#include "hmap/sim/builtin_scenes.hpp"

namespace hmap::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Pose pose_at(const Eigen::Vector3d& position, double yaw = 0.0) {
  Pose T = Pose::Identity();
  T.translation() = position;
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

double elevation_deg(const Point3f& p) {
  return std::atan2(static_cast<double>(p.z()), std::hypot(static_cast<double>(p.x()), static_cast<double>(p.y()))) / kDeg;
}

/// A 40 × 40 m wall whose face is the plane x = `distance`.
Scene wall_scene(double distance) {
  SceneBuilder builder;
  builder.add("wall", {{Box{{distance + 0.5, 0, 0}, {0.5, 20, 20}, 0.0}, SurfaceKind::kWall}});
  return builder.build();
}

void expect_rings_match(const SimulatedScan& scan, const std::vector<double>& elevations) {
  ASSERT_EQ(scan.channel.size(), scan.points_sensor.size());
  std::set<std::uint16_t> rings;
  for (std::size_t i = 0; i < scan.points_sensor.size(); ++i) {
    ASSERT_LT(scan.channel[i], elevations.size());
    rings.insert(scan.channel[i]);
    EXPECT_NEAR(elevation_deg(scan.points_sensor[i]), elevations[scan.channel[i]], 1e-3);
  }
  EXPECT_EQ(rings.size(), elevations.size());
}

TEST(SpinningLidar, Vlp16PatternInTheOffice) {
  const Scene office = make_office_scene();
  const SpinningLidarParams params = SpinningLidarParams::vlp16();
  SpinningLidar lidar(params);
  const SimulatedScan scan = lidar.scan(office, pose_at({5.0, 4.0, 1.2}, 0.3), 0.0);
  EXPECT_EQ(scan.rays, 1800U * 16U);
  EXPECT_EQ(scan.no_return, 0U);  // a closed room
  EXPECT_EQ(scan.rays, scan.points_sensor.size() + scan.no_return + scan.out_of_range + scan.dropped);
  EXPECT_GT(scan.dropped, 0.5 * 0.005 * static_cast<double>(scan.rays));
  EXPECT_LT(scan.dropped, 2.0 * 0.005 * static_cast<double>(scan.rays));
  expect_rings_match(scan, params.elevations_deg);
  for (std::size_t r = 0; r < 16; ++r) EXPECT_NEAR(params.elevations_deg[r], -15.0 + 2.0 * static_cast<double>(r), 1e-12);
  for (const auto& p : scan.points_sensor) {
    EXPECT_GE(p.norm(), params.min_range);
    EXPECT_LE(p.norm(), params.max_range);
  }
}

TEST(SpinningLidar, Os0RingsColumnsAndRangeLimits) {
  // 64 rings evenly over ±45°, 1024 columns, 0.3–50 m: in the closed office every ray returns
  // within range (or is dropped), and each point lies on its ring's cone.
  const SpinningLidarParams params = SpinningLidarParams::os0_64();
  ASSERT_EQ(params.elevations_deg.size(), 64U);
  EXPECT_NEAR(params.elevations_deg.front(), -45.0, 1e-12);
  EXPECT_NEAR(params.elevations_deg.back(), 45.0, 1e-12);
  EXPECT_NEAR(params.elevations_deg[1] - params.elevations_deg[0], 90.0 / 63.0, 1e-12);
  SpinningLidar lidar(params);
  const SimulatedScan scan = lidar.scan(make_office_scene(), pose_at({5.0, 4.0, 1.2}, 0.3), 0.0);
  EXPECT_EQ(scan.rays, 1024U * 64U);
  EXPECT_EQ(scan.no_return, 0U);
  EXPECT_EQ(scan.rays, scan.points_sensor.size() + scan.no_return + scan.out_of_range + scan.dropped);
  expect_rings_match(scan, params.elevations_deg);
  for (const auto& p : scan.points_sensor) {
    ASSERT_GE(p.norm(), params.min_range);
    ASSERT_LE(p.norm(), params.max_range);
  }
}

TEST(SpinningLidar, Hdl64RingsAndRangeLimits) {
  const SpinningLidarParams params = SpinningLidarParams::hdl64e();
  ASSERT_EQ(params.elevations_deg.size(), 64U);
  EXPECT_NEAR(params.elevations_deg.front(), 2.0, 1e-12);
  EXPECT_NEAR(params.elevations_deg[31], -8.333, 1e-3);
  EXPECT_NEAR(params.elevations_deg[32], -8.83, 1e-12);
  EXPECT_NEAR(params.elevations_deg.back(), -24.33, 1e-12);
  const Scene parking = make_parking_scene();
  SpinningLidar lidar(params);
  const SimulatedScan scan = lidar.scan(parking, pose_at({60.0, 1.6, 1.73}), 0.0);
  EXPECT_EQ(scan.rays, 2118U * 64U);
  EXPECT_GT(scan.points_sensor.size(), scan.rays / 2);
  expect_rings_match(scan, params.elevations_deg);
  for (const auto& p : scan.points_sensor) {
    ASSERT_GE(p.norm(), params.min_range);
    ASSERT_LE(p.norm(), params.max_range);
  }
}

TEST(SpinningLidar, RangeGateDropsTooNearAndTooFar) {
  SpinningLidarParams params;
  params.elevations_deg = {0.0};
  params.azimuth_step_deg = 1.0;
  params.range_sigma = 0.0;
  params.dropout_probability = 0.0;
  params.max_range = 10.0;
  SpinningLidar lidar(params);
  // Wall at 12 m: only beams within ±33.5° miss... none return since every range >= 12 > 10.
  EXPECT_TRUE(lidar.scan(wall_scene(12.0), Pose::Identity(), 0.0).points_sensor.empty());
  params.min_range = 3.0;
  SpinningLidar near_gate(params);
  const SimulatedScan scan = near_gate.scan(wall_scene(2.0), Pose::Identity(), 0.0);
  // The wall at 2 m is seen at 3..10 m only by beams between acos(2/3) = 48.2° and acos(2/10) = 78.5°.
  for (const auto& p : scan.points_sensor) {
    const double azimuth = std::abs(std::atan2(p.y(), p.x())) / kDeg;
    EXPECT_GT(azimuth, 48.0);
    EXPECT_LT(azimuth, 78.6);
  }
  EXPECT_EQ(scan.points_sensor.size(), 2U * 30U);  // 49..78° on both sides
}

TEST(SpinningLidar, SameSeedSameScanOtherSeedOtherScan) {
  const Scene office = make_office_scene();
  const Pose T = pose_at({4.0, 3.0, 1.0});
  SpinningLidarParams params = SpinningLidarParams::vlp16();
  SpinningLidar a(params);
  SpinningLidar b(params);
  params.seed = 2;
  SpinningLidar c(params);
  const SimulatedScan sa = a.scan(office, T, 0.0);
  EXPECT_EQ(sa.points_sensor, b.scan(office, T, 0.0).points_sensor);
  EXPECT_NE(sa.points_sensor, c.scan(office, T, 0.0).points_sensor);
  EXPECT_NE(sa.points_sensor, a.scan(office, T, 0.0).points_sensor);  // the next frame has new noise
}

TEST(SpinningLidar, RangeNoiseHasZeroMeanAndTheConfiguredSigma) {
  const Scene wall = wall_scene(5.0);
  SpinningLidarParams params;
  for (int e = -10; e <= 10; ++e) params.elevations_deg.push_back(e);
  params.azimuth_step_deg = 0.1;
  params.range_sigma = 0.03;
  params.dropout_probability = 0.0;
  SpinningLidar lidar(params);
  const SimulatedScan scan = lidar.scan(wall, Pose::Identity(), 0.0);
  double sum = 0.0;
  double sum_sq = 0.0;
  std::size_t n = 0;
  for (const auto& p : scan.points_sensor) {
    const Eigen::Vector3d d = p.cast<double>().normalized();
    const auto truth = wall.intersect(Eigen::Vector3d::Zero(), d, 0.0, 1000.0);
    ASSERT_TRUE(truth.has_value());
    const double residual = p.cast<double>().norm() - truth->distance;
    sum += residual;
    sum_sq += residual * residual;
    ++n;
  }
  ASSERT_GT(n, 20000U);
  const double mean = sum / static_cast<double>(n);
  const double sigma = std::sqrt(sum_sq / static_cast<double>(n) - mean * mean);
  EXPECT_LT(std::abs(mean), 4.0 * 0.03 / std::sqrt(static_cast<double>(n)));
  EXPECT_NEAR(sigma, 0.03, 0.03 * 0.03);
}

TEST(SpinningLidar, RejectsBadParameters) {
  SpinningLidarParams params = SpinningLidarParams::vlp16();
  params.elevations_deg.clear();
  EXPECT_THROW(SpinningLidar{params}, Error);
  params = SpinningLidarParams::vlp16();
  params.dropout_probability = 1.5;
  EXPECT_THROW(SpinningLidar{params}, Error);
  params = SpinningLidarParams::vlp16();
  params.min_range = 200.0;
  EXPECT_THROW(SpinningLidar{params}, Error);
}

TEST(DepthCamera, KinectFieldOfViewAndAxialNoise) {
  const double distance = 2.0;
  const Scene wall = wall_scene(distance);
  const DepthCameraParams params = DepthCameraParams::kinect_one();
  DepthCamera camera(params);
  const SimulatedScan scan = camera.scan(wall, Pose::Identity(), 0.0);
  EXPECT_EQ(scan.rays, 512U * 424U);
  EXPECT_EQ(scan.points_sensor.size(), scan.rays);
  double max_tan_y = 0.0;
  double max_tan_z = 0.0;
  double sum = 0.0;
  double sum_sq = 0.0;
  for (const auto& p : scan.points_sensor) {
    ASSERT_GT(p.x(), 0.0F);
    max_tan_y = std::max(max_tan_y, std::abs(static_cast<double>(p.y() / p.x())));
    max_tan_z = std::max(max_tan_z, std::abs(static_cast<double>(p.z() / p.x())));
    const double residual = p.x() - distance;
    sum += residual;
    sum_sq += residual * residual;
  }
  EXPECT_NEAR(max_tan_y, std::tan(35.3 * kDeg), 0.01);
  EXPECT_NEAR(max_tan_z, std::tan(30.0 * kDeg), 0.01);
  const double n = static_cast<double>(scan.points_sensor.size());
  const double mean = sum / n;
  const double expected_sigma = 0.0012 + 0.0019 * (distance - 0.4) * (distance - 0.4);
  EXPECT_LT(std::abs(mean), 4.0 * expected_sigma / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(sum_sq / n - mean * mean), expected_sigma, 0.03 * expected_sigma);
  // Image rows run from the top: the first row looks up (z > 0 in the sensor frame).
  EXPECT_EQ(scan.channel.front(), 0U);
  EXPECT_GT(scan.points_sensor.front().z(), 0.0F);
  EXPECT_GT(scan.points_sensor.front().y(), 0.0F);  // first column is on the left
}

TEST(DepthCamera, NothingBeyondMaxRange) {
  DepthCamera camera(DepthCameraParams::kinect_one());
  const SimulatedScan scan = camera.scan(wall_scene(5.0), Pose::Identity(), 0.0);
  EXPECT_TRUE(scan.points_sensor.empty());
  EXPECT_EQ(scan.out_of_range + scan.no_return, scan.rays);
}

TEST(LineScanner, TiltingSweepOfTheOffice) {
  const Scene office = make_office_scene();
  const LineScannerParams params = LineScannerParams::utm30lx_tilting();
  LineScanner scanner(params);
  const SimulatedScan scan = scanner.scan(office, pose_at({5.0, 4.0, 1.0}), 0.0);
  EXPECT_EQ(scan.rays, 1081U * 91U);
  EXPECT_GT(scan.points_sensor.size(), scan.rays * 9 / 10);
  for (std::size_t i = 0; i < scan.points_sensor.size(); ++i) {
    const Eigen::Vector3d p = scan.points_sensor[i].cast<double>();
    ASSERT_GE(p.norm(), params.min_range - 1e-6);
    ASSERT_LE(p.norm(), params.max_range + 1e-6);
    // Step k pitches the scan plane by −45° + k°: the point lies in that plane.
    const double pitch = (-45.0 + scan.channel[i]) * kDeg;
    const Eigen::Vector3d plane_normal = Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) * Eigen::Vector3d::UnitZ();
    ASSERT_NEAR(plane_normal.dot(p), 0.0, 1e-4);
    // And within the 270° field of view: no beam looks straight back.
    const Eigen::Vector3d in_plane = Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitY()) * p;
    ASSERT_LE(std::abs(std::atan2(in_plane.y(), in_plane.x())), 135.0 * kDeg + 1e-6);
  }
}

TEST(LineScanner, YawingSweepCoversAllAround) {
  const Scene office = make_office_scene();
  LineScanner scanner(LineScannerParams::utm30lx_yawing());
  const SimulatedScan scan = scanner.scan(office, pose_at({5.0, 4.0, 1.0}), 0.0);
  EXPECT_EQ(scan.rays, 1081U * 181U);
  bool up = false;
  bool down = false;
  bool behind = false;
  for (std::size_t i = 0; i < scan.points_sensor.size(); ++i) {
    const Eigen::Vector3d p = scan.points_sensor[i].cast<double>();
    const double yaw = scan.channel[i] * kDeg;
    ASSERT_NEAR(-std::sin(yaw) * p.x() + std::cos(yaw) * p.y(), 0.0, 1e-4);
    up = up || p.z() > 1.5;
    down = down || p.z() < -0.9;
    behind = behind || p.x() < -3.0;
  }
  EXPECT_TRUE(up && down && behind);
}

TEST(LineScanner, SweepTimeMovesObjects) {
  // A box that jumps away at t = 0.5 s: the first line scans see it, the last do not.
  SceneBuilder builder;
  builder.add_moving("box", {{Box{{0, 0, 0}, {0.5, 0.5, 0.5}, 0.0}, SurfaceKind::kBox}},
                     MotionPath({{0.0, {3, 0, 0}, 0.0}, {0.5, {3, 0, 0}, 0.0}, {0.51, {3, 50, 0}, 0.0}}));
  LineScannerParams params = LineScannerParams::utm30lx_tilting();
  params.sweep_min_deg = -5.0;
  params.sweep_max_deg = 5.0;
  params.sweep_steps = 41;  // 1 s at 40 Hz
  LineScanner scanner(params);
  const SimulatedScan scan = scanner.scan(builder.build(), Pose::Identity(), 0.0);
  std::set<std::uint16_t> steps(scan.channel.begin(), scan.channel.end());
  ASSERT_FALSE(steps.empty());
  EXPECT_EQ(*steps.begin(), 0U);
  EXPECT_EQ(*steps.rbegin(), 20U);  // t = 0.5 s
}

}  // namespace
}  // namespace hmap::sim
