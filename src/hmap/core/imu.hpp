#pragma once
// An inertial measurement as plain data, shared by the readers (io, ros) and the SLAM prior (slam).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <vector>

namespace hmap {

/// One IMU sample in the IMU's own frame.
struct ImuSample {
  double t = 0.0;                                  ///< [s] stamp
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();  ///< [rad/s] angular velocity
  /// [m/s²] specific force (what an accelerometer measures): +9.81 along the IMU's up when at rest.
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
  /// The IMU's own orientation estimate (world ← imu), when the recording has one.
  std::optional<Eigen::Quaterniond> orientation;
};

using ImuSamples = std::vector<ImuSample>;

}  // namespace hmap
