#pragma once
// An attitude prior from an IMU between scans (issue 16): the gravity direction from the
// accelerometer, low-passed against the gyro by a complementary filter, and the rotation between
// consecutive scans from integrating the gyro. Pure: samples in, priors out.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <span>
#include <vector>

#include "hmap/core/imu.hpp"
#include "hmap/core/params.hpp"

namespace hmap::slam {

/// What the IMU says about one scan, in the sensor frame (R_sensor_imu applied).
struct ImuPrior {
  Eigen::Vector3d up_sensor = Eigen::Vector3d::UnitZ();  ///< gravity's upward unit direction at the scan
  /// The sensor's rotation since the previous scan (gyro integrated; identity for the first).
  Eigen::Matrix3d R_previous_current = Eigen::Matrix3d::Identity();
  bool has_rotation = false;  ///< false for the first scan (nothing to integrate from)
  /// [rad/s] mean angular velocity over [t, t + sweep], for deskewing.
  Eigen::Vector3d angular_velocity_sensor = Eigen::Vector3d::Zero();
  std::size_t samples = 0;  ///< IMU samples integrated since the previous scan
};

/// R_sensor_imu from slam.imu_roll, imu_pitch, imu_yaw.
[[nodiscard]] Eigen::Matrix3d imu_mounting(const SlamParams& params);

/// Runs the filter through the samples, scan by scan (stamps increasing).
///
/// Tilt (complementary filter): the orientation R_world_imu is propagated by each gyro sample
/// (R ← R·Exp(ω·dt)) and its up direction Rᵀ·z turned toward the measured specific force a/|a| by
/// the fraction dt / (τ + dt), τ = slam.imu_gravity_time_constant; samples with ||a| − g| over
/// slam.imu_accel_gate·g do not correct (the sensor accelerates). Samples that carry the IMU's own
/// orientation use it instead. The centripetal part of the specific force is taken off with the
/// velocity last set (set_body_velocity; zero by default). Rotation between scans: the gyro alone, integrated between the two
/// stamps (the last sample's rate held up to a stamp).
class ImuAttitudeFilter {
 public:
  /// Throws hmap::Error for no samples, a non-finite value or stamps that do not increase.
  ImuAttitudeFilter(ImuSamples samples, const Params& params);

  /// The prior at stamp `t` (not before the previous call's); `sweep` [s] is the span the mean
  /// angular velocity is taken over (0: the rate at t).
  [[nodiscard]] ImuPrior prior_at(double t, double sweep = 0.0);

  /// The sensor's velocity in its own frame [m/s] now (SLAM's estimate). The accelerometer measures
  /// gravity plus the acceleration of a turn (0.35 m/s², 2° of tilt, walking at 1 m/s through a
  /// 20°/s turn): from here on the velocity is taken to turn with the heading (the gyro's rate about
  /// the world's z), and that centripetal acceleration is taken off before the tilt is corrected.
  void set_body_velocity(const Eigen::Vector3d& v_sensor);

  /// The prior for a scan stamped `t` whose points' times are `times_s` ([s]; the sweep is their
  /// latest, 0 without), with `v_sensor` the velocity SLAM estimates now (HmapSlam::velocity): the
  /// two calls above, as `hmap slam --imu` and hmap.slam.Slam make them before each scan.
  [[nodiscard]] ImuPrior prior_for_scan(double t, std::span<const float> times_s, const Eigen::Vector3d& v_sensor);

  [[nodiscard]] const ImuSamples& samples() const { return samples_; }

 private:
  void start();
  void advance_to(double t);
  [[nodiscard]] Eigen::Vector3d rate_at(double t) const;

  ImuSamples samples_;
  SlamParams params_;
  Eigen::Matrix3d R_sensor_imu_;
  Eigen::Matrix3d R_world_imu_ = Eigen::Matrix3d::Identity();  // the filtered orientation
  Eigen::Matrix3d R_gyro_ = Eigen::Matrix3d::Identity();       // the gyro alone, from the start
  Eigen::Matrix3d R_gyro_at_last_scan_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d v_world_ = Eigen::Vector3d::Zero();  // [m/s] velocity in the filter's world frame
  double now_ = 0.0;          // the time the state is at
  std::size_t next_ = 0;      // first sample not yet applied
  std::size_t applied_since_scan_ = 0;
  std::size_t corrections_ = 0;  // accelerometer corrections so far
  bool started_ = false;
  bool scanned_ = false;
};

}  // namespace hmap::slam
