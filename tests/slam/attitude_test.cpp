// The z / roll / pitch half of the 6-DoF SLAM (slam/attitude.hpp): the floor normal, the tilt that
// aligns it, the fit against the map, and HmapSlam with no attitude given.

#include "hmap/slam/attitude.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <numbers>

#include "hmap/sim/composites.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"
#include "hmap/sim/trajectory.hpp"
#include "hmap/slam/hmap_slam.hpp"

namespace hmap::slam {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// A yard with a flat ground, walls of different heights, a table top, a box and a ceiling strip:
/// horizontal surfaces spread in x and y (z, roll, pitch observable) and vertical ones (x, y, yaw).
sim::Scene yard() {
  sim::SceneBuilder b;
  b.add("ground", sim::make_ground({-25, -20}, {25, 20}, 0.0));
  b.add("north", sim::make_wall({-14, 12}, {14, 12}, 3.0));
  b.add("south", sim::make_wall({-14, -12}, {8, -12}, 4.0));
  b.add("west", sim::make_wall({-14, -12}, {-14, 12}, 2.5));
  b.add("east", sim::make_wall({12, -6}, {12, 10}, 3.5));
  b.add("box", {{sim::Box{{4, -5, 0.6}, {1.0, 0.5, 0.6}, 0.4}, sim::SurfaceKind::kBox}});
  b.add("kiosk", {{sim::Box{{-6, 4, 1.5}, {2.0, 1.5, 1.5}, 0.3}, sim::SurfaceKind::kWall}});
  b.add("platform", {{sim::Box{{7, 6, 0.4}, {2.5, 2.0, 0.4}, 0.0}, sim::SurfaceKind::kBox}});
  return b.build();
}

Params fine_params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.1;
  p.map.max_range = 20.0;
  p.slam.min_layer_height = 0.1;
  return p;
}

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0));
}

TEST(Attitude, TiltAligningTurnsTheNormalOntoTheTarget) {
  // Hand-checkable: a sensor rolled by +10° sees the floor normal at Rx(−10°)·z; the tilt that
  // turns it back onto z is roll = +10°, pitch = 0.
  const Eigen::Vector3d n = Eigen::AngleAxisd(-10 * kDeg, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitZ();
  const Attitude a = tilt_aligning(n, Eigen::Vector3d::UnitZ(), Attitude{1.5, 0.0, 0.0});
  EXPECT_NEAR(a.roll, 10 * kDeg, 1e-9);
  EXPECT_NEAR(a.pitch, 0.0, 1e-9);
  EXPECT_DOUBLE_EQ(a.z, 1.5);
  // Any tilt and target: R·n lands on the target (yaw is not used, so it must be reached by roll
  // and pitch alone).
  const Eigen::Vector3d n2 = Eigen::Vector3d(0.2, -0.3, 0.9).normalized();
  const Eigen::Vector3d t2 = Eigen::Vector3d(-0.05, 0.04, 1.0).normalized();
  const Attitude b = tilt_aligning(n2, t2, Attitude{});
  EXPECT_LT(angle_between(level_rotation(b) * n2, t2), 1e-9);
}

TEST(Attitude, FloorNormalOfATiltedScan) {
  // An HDL-64 rolled 10° and pitched −4° over flat ground: the floor normal found in the sensor
  // frame is the world's up seen from the sensor, within 0.2°.
  const sim::Scene scene = yard();
  const Params p = fine_params();
  sim::SpinningLidar lidar(sim::SpinningLidarParams::hdl64e());
  const Attitude truth{1.8, 10 * kDeg, -4 * kDeg};
  const Pose T = compose(PlanarPose{1.0, -2.0, 0.3}, truth);
  const PointCloud scan = lidar.scan(scene, T, 0.0).points_sensor;
  ScanHVoxelizer hv(p.map);
  ScanHVoxels sensor_frame;
  hv.build(scan, Pose::Identity(), sensor_frame);
  const auto n = floor_normal(sensor_frame, p);
  ASSERT_TRUE(n.has_value());
  const Eigen::Vector3d up_in_sensor = T.linear().transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(angle_between(*n, up_in_sensor), 0.2 * kDeg);
  // Nothing below the sensor: no floor.
  PointCloud above;
  for (const Point3f& q : scan) {
    if (q.z() > 0.5F) above.push_back(q);
  }
  hv.build(above, Pose::Identity(), sensor_frame);
  EXPECT_FALSE(floor_normal(sensor_frame, p).has_value());
}

TEST(Attitude, RefinerRecoversHeightAndTiltAgainstTheMap) {
  // A map from a level scan; a second scan from 0.5 m away, 6 cm higher, rolled 2° and pitched
  // −1.5°, refined from a level guess at the wrong height with the true planar pose: z, roll and
  // pitch within 2 cm and 0.2°, all three observable.
  const sim::Scene scene = yard();
  const Params p = fine_params();
  sim::SpinningLidar lidar(sim::SpinningLidarParams::hdl64e());
  Mapper mapper(p);
  const Attitude level{1.8, 0.0, 0.0};
  mapper.integrate(lidar.scan(scene, compose(PlanarPose{}, level), 0.0).points_sensor, compose(PlanarPose{}, level));
  const PlanarPose xi{0.4, -0.3, 3 * kDeg};
  const Attitude truth{1.86, 2 * kDeg, -1.5 * kDeg};
  const PointCloud scan = lidar.scan(scene, compose(xi, truth), 0.1).points_sensor;
  const Attitude guess{1.8, 0.0, 0.0};
  ScanHVoxelizer hv(p.map);
  ScanHVoxels scan_level;
  hv.build(scan, compose(PlanarPose{}, guess), scan_level);
  AttitudeRefiner refiner(p);
  const AttitudeFit fit = refiner.refine(scan_level, mapper.map(), xi.x, xi.y, xi.yaw, guess);
  EXPECT_TRUE(fit.ran);
  EXPECT_NEAR(fit.attitude.z, truth.z, 0.02);
  EXPECT_NEAR(fit.attitude.roll, truth.roll, 0.2 * kDeg);
  EXPECT_NEAR(fit.attitude.pitch, truth.pitch, 0.2 * kDeg);
  EXPECT_TRUE(fit.observable[0] && fit.observable[1] && fit.observable[2]);
  EXPECT_GT(fit.surfaces, 1000U);
  EXPECT_LT(fit.rms, 0.05);
  // No map: nothing to pair, the guess is kept and nothing is observable.
  const AttitudeFit none = refiner.refine(scan_level, HMap(p), xi.x, xi.y, xi.yaw, guess);
  EXPECT_EQ(none.attitude.z, guess.z);
  EXPECT_EQ(none.attitude.roll, 0.0);
  EXPECT_FALSE(none.observable[0] || none.observable[1] || none.observable[2]);
}

TEST(Attitude, SlamRecoversAKnownSixDofTransformFromTheScansAlone) {
  // Two scans, no attitude given: the second's pose relative to the first is the true one within
  // 2 cm and 0.2° in every axis.
  const sim::Scene scene = yard();
  const Params p = fine_params();
  sim::SpinningLidar lidar(sim::SpinningLidarParams::hdl64e());
  const Pose T0 = compose(PlanarPose{}, Attitude{1.8, 0.0, 0.0});
  const Pose T1 = compose(PlanarPose{0.3, -0.2, 4 * kDeg}, Attitude{1.85, 2 * kDeg, -3 * kDeg});
  HmapSlam slam(p);
  const SlamStep s0 = slam.process(lidar.scan(scene, T0, 0.0).points_sensor, std::nullopt);
  const SlamStep s1 = slam.process(lidar.scan(scene, T1, 0.1).points_sensor, std::nullopt);
  ASSERT_TRUE(s1.matched);
  const Pose rel_true = T0.inverse() * T1;
  const Pose rel_est = s0.T_map_sensor.inverse() * s1.T_map_sensor;
  const Eigen::Vector3d dt = rel_est.translation() - rel_true.translation();
  EXPECT_LT(std::abs(dt.x()), 0.02);
  EXPECT_LT(std::abs(dt.y()), 0.02);
  EXPECT_LT(std::abs(dt.z()), 0.02);
  const Attitude at = attitude_of(rel_est);
  const Attitude aw = attitude_of(rel_true);
  EXPECT_NEAR(at.roll, aw.roll, 0.2 * kDeg);
  EXPECT_NEAR(at.pitch, aw.pitch, 0.2 * kDeg);
  EXPECT_NEAR(planar_of(rel_est).yaw, planar_of(rel_true).yaw, 0.2 * kDeg);
  for (bool o : s1.observable) EXPECT_TRUE(o);
}

TEST(Attitude, TiltedSensorOnFlatGroundIsLevelled) {
  // A sensor rolled 10° driving over flat ground, no attitude given: every estimated roll is 10°
  // (the map's z is the floor normal) within 0.3°, pitch 0, and the height stays that of the
  // first scan within 2 cm.
  const sim::Scene scene = yard();
  const Params p = fine_params();
  sim::SpinningLidar lidar(sim::SpinningLidarParams::hdl64e());
  HmapSlam slam(p);
  for (int k = 0; k < 5; ++k) {
    const PlanarPose xi{0.1 * k, 0.02 * k, 0.5 * kDeg * k};
    const Pose T = compose(xi, Attitude{1.8, 10 * kDeg, 0.0});
    const SlamStep step = slam.process(lidar.scan(scene, T, 0.1 * k).points_sensor, std::nullopt);
    const Attitude a = attitude_of(step.T_map_sensor);
    EXPECT_NEAR(a.roll, 10 * kDeg, 0.3 * kDeg) << k;
    EXPECT_NEAR(a.pitch, 0.0, 0.3 * kDeg) << k;
    EXPECT_NEAR(a.z, 0.0, 0.02) << k;
  }
}

TEST(Attitude, DegenerateCorridorIsReportedPerAxis) {
  // A corridor of two long walls along x, lower than the sensor (taller ones show the rings'
  // pattern, a feature along x), on a floor, nothing closing it: x is not observable, y and yaw
  // are; z and pitch are (the floor runs along x).
  sim::SceneBuilder b;
  b.add("floor", sim::make_ground({-200, -2}, {200, 2}, 0.0));
  b.add("left", sim::make_wall({-200, 2.0}, {200, 2.0}, 1.0));
  b.add("right", sim::make_wall({-200, -2.0}, {200, -2.0}, 1.0));
  const sim::Scene scene = b.build();
  Params p = fine_params();
  sim::SpinningLidar lidar(sim::SpinningLidarParams::hdl64e());
  HmapSlam slam(p);
  // The map from scans 12 m apart (their x given, as odometry would), so that neither the map's end
  // nor the rings' pattern on the walls is a feature; then a scan 0.3 m on from a guess at 0.1 m.
  SlamStep last;
  const std::array<double, 4> xs{-12.0, 0.0, 12.0, 0.4};
  const std::array<double, 4> guesses{-12.0, 0.0, 12.0, 0.1};
  for (std::size_t k = 0; k < xs.size(); ++k) {
    last = slam.process(
        lidar.scan(scene, compose(PlanarPose{xs[k], 0.0, 0.0}, Attitude{1.2, 0, 0}), 0.1 * static_cast<double>(k))
            .points_sensor,
        std::nullopt, PlanarPose{guesses[k], 0.0, 0.0});
  }
  ASSERT_TRUE(last.matched);
  EXPECT_TRUE(last.match.degenerate);
  EXPECT_FALSE(last.observable[0]);  // x, along the corridor
  EXPECT_TRUE(last.observable[1]);   // y
  EXPECT_TRUE(last.observable[2]);   // z
  EXPECT_TRUE(last.observable[4]);   // pitch: the floor runs along x
  EXPECT_TRUE(last.observable[5]);   // yaw
}

TEST(Attitude, RampBetweenTwoLevelFloorsKeepsItsPitch) {
  // A car (VLP-16, 10 Hz) drives over a level floor, up a 10° ramp between walls and on over the
  // level floor at its top, with planar odometry as the guess and no attitude given. At the ramp's
  // foot and top the scan's dominant floor is not the one the last scan stood on (the ramp ahead,
  // the ramp behind): the floor's tilt prediction is then off by the slope. Every pitch within 0.6°
  // of the truth and the height at the end within 0.15 m. With the floor's prediction and the last
  // tilt as the only hypotheses, the top was 8.7° off and the end 2.5 m too high (the third, the
  // tilt that levels the dominant floor, is the right one there).
  constexpr double kSlope = 0.17633;  // tan 10°
  constexpr double kTop = 12.0 * kSlope;
  sim::SceneBuilder b;
  b.add("low", sim::make_ground({-30, -8}, {0, 8}, 0.0));
  b.add("ramp", {{sim::GroundPatch{{6.0, 0.0, 0.5 * kTop}, {6.0, 8.0}, 0.0, {kSlope, 0.0}, 0.5},
                  sim::SurfaceKind::kGround}});
  b.add("high", sim::make_ground({12, -8}, {40, 8}, kTop));
  b.add("north", sim::make_wall({-30, 8}, {40, 8}, 6.0, 0.2, -1.0));
  b.add("south", sim::make_wall({-30, -8}, {40, -8}, 6.0, 0.2, -1.0));
  b.add("back", sim::make_wall({-30, -8}, {-30, 8}, 4.0, 0.2, -1.0));
  b.add("front", sim::make_wall({40, -8}, {40, 8}, 4.0, 0.2, kTop - 1.0));
  for (const double x : {-20.0, -10.0, 20.0, 30.0}) {
    for (const double y : {-4.0, 4.0}) {
      b.add("pillar", {{sim::Box{{x, y, 1.5}, {0.3, 0.3, 1.5 + 2.5}, 0.0}, sim::SurfaceKind::kPillar}});
    }
  }
  const sim::Scene scene = b.build();
  Params p = outdoor_preset();
  p.map.max_range = 25.0;
  sim::CarPathParams cp;
  cp.cruise_speed = 3.0;
  const std::array<Eigen::Vector3d, 4> route{Eigen::Vector3d{-22, 0, 0}, Eigen::Vector3d{0, 0, 0},
                                             Eigen::Vector3d{12, 0, kTop}, Eigen::Vector3d{30, 0, kTop}};
  const sim::Trajectory path = sim::car_path(route, cp);
  sim::SpinningLidar lidar(sim::SpinningLidarParams::vlp16());
  HmapSlam slam(p);
  slam.start_at_height(path.T_world_sensor.front().translation().z());
  double worst_pitch = 0.0;
  int last_tilt_won = 0;
  SlamStep step;
  for (std::size_t k = 0; k < path.T_world_sensor.size(); ++k) {
    const Pose& T = path.T_world_sensor[k];
    std::optional<PlanarPose> guess = planar_of(T);
    step = slam.process(lidar.scan(scene, T, path.times[k]).points_sensor, std::nullopt, guess);
    worst_pitch = std::max(worst_pitch, std::abs(attitude_of(step.T_map_sensor).pitch - attitude_of(T).pitch));
    last_tilt_won += step.tilt_hypotheses == 2 && !step.tilt_from_floor ? 1 : 0;
  }
  EXPECT_LT(worst_pitch, 0.6 * kDeg);
  EXPECT_NEAR(step.T_map_sensor.translation().z(), path.T_world_sensor.back().translation().z(), 0.15);
  EXPECT_GT(last_tilt_won, 0);
}

}  // namespace
}  // namespace hmap::slam
