#include "hmap/sim/trajectory.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "hmap/core/error.hpp"
#include "hmap/sim/builtin_scenes.hpp"

namespace hmap::sim {
namespace {

double yaw_of(const Pose& T) { return std::atan2(T.linear()(1, 0), T.linear()(0, 0)); }

TEST(DiffDrive, DrivesStraightAndTurnsOnTheSpot) {
  const std::vector<Eigen::Vector2d> route = office_robot_route();
  DiffDriveParams params;
  const Trajectory path = diff_drive_path(route, params);
  ASSERT_EQ(path.T_world_sensor.size(), path.times.size());
  ASSERT_GT(path.times.size(), 100U);
  EXPECT_TRUE(path.T_world_sensor.front().translation().isApprox(Eigen::Vector3d(1.0, 1.0, 0.5)));
  EXPECT_NEAR(yaw_of(path.T_world_sensor.front()), 0.0, 1e-12);
  EXPECT_LT((path.T_world_sensor.back().translation().head<2>() - route.back()).norm(), params.speed / params.frame_rate);
  for (std::size_t i = 1; i < path.times.size(); ++i) {
    EXPECT_NEAR(path.times[i] - path.times[i - 1], 0.1, 1e-12);
    const Pose step = path.T_world_sensor[i - 1].inverse() * path.T_world_sensor[i];
    EXPECT_LE(step.translation().norm(), params.speed * 0.1 + 1e-9);
    EXPECT_LE(Eigen::AngleAxisd(step.linear()).angle(), params.turn_rate * 0.1 + 1e-9);
    if (Eigen::AngleAxisd(step.linear()).angle() < 1e-12) {
      EXPECT_NEAR(step.translation().y(), 0.0, 1e-9);  // no sideways motion while driving straight
    }
    EXPECT_NEAR(path.T_world_sensor[i].translation().z(), 0.5, 1e-12);
  }
  EXPECT_THROW((void)diff_drive_path(std::span(route).first(1), params), Error);
}

TEST(CarPath, RespectsSpeedAndAccelerationAndFollowsTheRamp) {
  const std::vector<Eigen::Vector3d> route = parking_car_route();
  CarPathParams params;
  const Trajectory path = car_path(route, params);
  ASSERT_GT(path.times.size(), 200U);
  const double dt = 1.0 / params.frame_rate;
  EXPECT_LT((path.T_world_sensor.front().translation() - (route.front() + Eigen::Vector3d(0, 0, 1.73))).norm(), 1e-9);
  EXPECT_LT((path.T_world_sensor.back().translation() - (route.back() + Eigen::Vector3d(0, 0, 1.73))).norm(), 0.2);
  std::vector<double> speed;
  for (std::size_t i = 1; i < path.times.size(); ++i) {
    speed.push_back((path.T_world_sensor[i].translation() - path.T_world_sensor[i - 1].translation()).norm() / dt);
    EXPECT_LE(speed.back(), params.cruise_speed + 1e-6);
  }
  // The first and last second are left out: the path is sampled every 5 cm, and the time of the
  // first and last sample step is coarse against 0.1 s frames.
  for (std::size_t i = 11; i + 11 < speed.size(); ++i) {
    EXPECT_LE(std::abs(speed[i] - speed[i - 1]) / dt, 1.2 * params.acceleration) << "frame " << i;
  }
  EXPECT_LT(speed.front(), 0.2);
  EXPECT_LT(speed.back(), 1.0);
  EXPECT_GT(*std::max_element(speed.begin(), speed.end()), 0.95 * params.cruise_speed);
  // On the ramp (x in [2, 18]) the sensor is pitched nose up by atan(0.175).
  bool on_ramp = false;
  for (const Pose& T : path.T_world_sensor) {
    const double x = T.translation().x();
    if (x < 2.0 || x > 18.0) continue;
    on_ramp = true;
    const Eigen::Vector3d forward = T.linear().col(0);
    EXPECT_NEAR(std::atan2(forward.z(), forward.head<2>().norm()), std::atan(0.175), 1e-6);
    EXPECT_NEAR(T.translation().z(), -3.5 + 0.175 * x + 1.73, 1e-3);
  }
  EXPECT_TRUE(on_ramp);
  // The left turn into the side road: the last frames head north.
  EXPECT_NEAR(yaw_of(path.T_world_sensor.back()), 0.5 * std::numbers::pi, 1e-6);
}

TEST(NoisyOdometry, ZeroNoiseIsTheTruthAndNoiseIsSeeded) {
  const Trajectory path = diff_drive_path(office_robot_route(), DiffDriveParams{});
  OdometryNoiseParams none{0.0, 0.0, 0.0, 0.0, OdometryNoiseAxes::kFull, 1};
  const PoseList exact = noisy_odometry(path.T_world_sensor, none);
  ASSERT_EQ(exact.size(), path.T_world_sensor.size());
  for (std::size_t i = 0; i < exact.size(); ++i) EXPECT_TRUE(exact[i].isApprox(path.T_world_sensor[i], 1e-9));

  OdometryNoiseParams noise;
  const PoseList a = noisy_odometry(path.T_world_sensor, noise);
  const PoseList b = noisy_odometry(path.T_world_sensor, noise);
  noise.seed = 2;
  const PoseList c = noisy_odometry(path.T_world_sensor, noise);
  EXPECT_TRUE(a.back().isApprox(b.back(), 0.0));
  EXPECT_FALSE(a.back().isApprox(c.back(), 1e-6));
  EXPECT_TRUE(a.front().isApprox(path.T_world_sensor.front(), 0.0));
  // Planar noise keeps the height and the roll and pitch.
  for (const Pose& T : a) {
    EXPECT_NEAR(T.translation().z(), 0.5, 1e-9);
    EXPECT_NEAR(T.linear()(2, 2), 1.0, 1e-9);
  }
  EXPECT_TRUE(noisy_odometry({}, noise).empty());
}

TEST(NoisyOdometry, StepErrorsHaveTheConfiguredSigma) {
  // A robot standing still: every relative motion is the identity, so each step's error is pure noise.
  const PoseList still(4000, Pose::Identity());
  OdometryNoiseParams noise{0.01, 0.0, 0.002, 0.0, OdometryNoiseAxes::kFull, 3};
  const PoseList odometry = noisy_odometry(still, noise);
  double sum_sq_t = 0.0;
  double sum_sq_r = 0.0;
  for (std::size_t i = 1; i < odometry.size(); ++i) {
    const Pose step = odometry[i - 1].inverse() * odometry[i];
    sum_sq_t += step.translation().squaredNorm();
    sum_sq_r += std::pow(Eigen::AngleAxisd(step.linear()).angle(), 2);
  }
  const double n = static_cast<double>(odometry.size() - 1);
  EXPECT_NEAR(std::sqrt(sum_sq_t / (3.0 * n)), 0.01, 0.0005);
  EXPECT_NEAR(std::sqrt(sum_sq_r / (3.0 * n)), 0.002, 0.0001);
}

TEST(StopAndGo, RestsAtEveryStopAndMovesBetween) {
  PoseList stops(3, Pose::Identity());
  stops[1].translation() = Eigen::Vector3d(0.0, 0.5, 0.0);
  stops[2].translation() = Eigen::Vector3d(0.0, 1.0, 0.0);
  stops[2].linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  StopAndGoParams params;
  const StopAndGo run = stop_and_go(stops, params);
  ASSERT_EQ(run.stop.size(), run.trajectory.times.size());
  // 3 s at rest, 2 × 2.5 s moving: 8 s, 81 frames.
  EXPECT_EQ(run.trajectory.times.size(), 81U);
  std::vector<int> frames_at(3, 0);
  for (std::size_t i = 0; i < run.stop.size(); ++i) {
    if (run.stop[i] < 0) continue;
    ++frames_at[static_cast<std::size_t>(run.stop[i])];
    EXPECT_TRUE(run.trajectory.T_world_sensor[i].isApprox(stops[static_cast<std::size_t>(run.stop[i])], 1e-12));
  }
  for (const int n : frames_at) EXPECT_GE(n, 10);
  EXPECT_EQ(run.stop.front(), 0);
  EXPECT_EQ(run.stop.back(), 2);
  EXPECT_TRUE(std::find(run.stop.begin(), run.stop.end(), -1) != run.stop.end());
  EXPECT_THROW((void)stop_and_go({}, params), Error);
}

}  // namespace
}  // namespace hmap::sim

namespace hmap::sim {
namespace {

// pose_at: the frames themselves at their times; along a straight line at constant speed the
// spline is the line (position linear in t, so zero acceleration for a simulated IMU); a quarter
// turn halfway is 45 degrees; clamped outside; an empty trajectory refused.
TEST(PoseAt, FramesLinesAndClamping) {
  Trajectory tr;
  for (int k = 0; k < 5; ++k) {
    Pose T = Pose::Identity();
    T.translation() = Eigen::Vector3d(2.0 * k, 1.0, 0.5);
    T.linear() = Eigen::AngleAxisd(k == 4 ? std::numbers::pi / 2 : 0.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    tr.T_world_sensor.push_back(T);
    tr.times.push_back(0.1 * k);
  }
  for (int k = 0; k < 5; ++k) {
    EXPECT_TRUE(pose_at(tr, 0.1 * k).isApprox(tr.T_world_sensor[static_cast<std::size_t>(k)], 1e-12)) << k;
  }
  EXPECT_NEAR(pose_at(tr, 0.137).translation().x(), 2.74, 1e-12);
  EXPECT_NEAR(pose_at(tr, 0.137).translation().y(), 1.0, 1e-12);
  const double yaw = Eigen::AngleAxisd(pose_at(tr, 0.35).linear()).angle();
  EXPECT_NEAR(yaw, std::numbers::pi / 4, 1e-9);
  EXPECT_TRUE(pose_at(tr, -1.0).isApprox(tr.T_world_sensor.front()));
  EXPECT_TRUE(pose_at(tr, 9.0).isApprox(tr.T_world_sensor.back()));
  EXPECT_THROW((void)pose_at(Trajectory{}, 0.0), Error);
}

}  // namespace
}  // namespace hmap::sim
