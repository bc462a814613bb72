#pragma once
// A simulated IMU riding on a sensor trajectory: the gyro's angular velocity and the
// accelerometer's specific force (gravity included) from the trajectory's derivatives, with
// Gaussian noise and a constant gyro bias from a fixed seed.

#include <Eigen/Core>
#include <cstdint>
#include <functional>

#include "hmap/core/imu.hpp"
#include "hmap/core/types.hpp"

namespace hmap::sim {

struct ImuSimParams {
  double rate = 200.0;                                   ///< [Hz] samples per second
  double gyro_sigma = 0.003;                             ///< [rad/s] σ of the white gyro noise
  double accel_sigma = 0.05;                             ///< [m/s²] σ of the white accelerometer noise
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();   ///< [rad/s] constant gyro bias
  Eigen::Matrix3d R_sensor_imu = Eigen::Matrix3d::Identity();  ///< the IMU's mounting
  std::uint64_t seed = 1;
};

/// The samples from t0 to t1 (inclusive, every 1 / rate) of an IMU on the sensor whose pose is
/// T_world_sensor_at(t) (world z up, g = 9.80665 m/s²), in the IMU frame. Derivatives by central
/// differences over 1 ms. Throws hmap::Error for a non-positive rate or t1 < t0.
[[nodiscard]] ImuSamples simulate_imu(const std::function<Pose(double)>& T_world_sensor_at, double t0, double t1,
                                      const ImuSimParams& params);

}  // namespace hmap::sim
