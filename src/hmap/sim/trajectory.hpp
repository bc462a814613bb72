#pragma once
// Scripted sensor trajectories (ground truth) and the noisy odometry a robot would integrate.

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "hmap/core/types.hpp"

namespace hmap::sim {

/// True sensor poses at the frame times.
struct Trajectory {
  PoseList T_world_sensor;
  std::vector<double> times;  ///< [s], one per pose, starting at 0
};

/// The pose at time t [s] between the frames: positions on the Catmull-Rom spline through the
/// frame positions (so velocity is continuous and an IMU simulated on it sees a finite
/// acceleration), rotations slerped between neighbouring frames. Clamped to the first and last
/// frame outside [times.front(), times.back()]. Throws hmap::Error for an empty trajectory or one
/// whose times do not increase.
[[nodiscard]] Pose pose_at(const Trajectory& trajectory, double t);

/// A differential-drive robot: drives straight between waypoints and turns on the spot at them.
struct DiffDriveParams {
  double speed = 0.5;          ///< [m/s]
  double turn_rate = 0.6;      ///< [rad/s] when turning on the spot
  double frame_rate = 10.0;    ///< [Hz]
  double sensor_height = 0.5;  ///< [m] above the floor
  double floor_z = 0.0;        ///< [m]
};
/// Frames from t = 0 until the last waypoint is reached; the robot starts facing the second
/// waypoint. Throws hmap::Error for fewer than two waypoints or non-positive rates.
[[nodiscard]] Trajectory diff_drive_path(std::span<const Eigen::Vector2d> waypoints, const DiffDriveParams& params);

/// A car following a polyline of ground points whose corners are rounded into circular arcs.
struct CarPathParams {
  double cruise_speed = 8.0;          ///< [m/s]
  double acceleration = 1.5;          ///< [m/s²] for speeding up and braking
  double lateral_acceleration = 2.0;  ///< [m/s²] bounds the speed in turns, v² = a_lat · radius
  double turn_radius = 6.0;           ///< [m] of the arcs (smaller where segments are short)
  double frame_rate = 10.0;           ///< [Hz]
  double sensor_height = 1.73;        ///< [m] above the ground point, along world z
};
/// Starts and stops at rest. The sensor's yaw follows the heading and its pitch the slope of the
/// path (ramps). Throws hmap::Error for fewer than two waypoints or non-positive parameters.
[[nodiscard]] Trajectory car_path(std::span<const Eigen::Vector3d> waypoints_ground, const CarPathParams& params);

/// Which axes the odometry noise acts on.
enum class OdometryNoiseAxes : std::uint8_t {
  kPlanar,  ///< x, y and yaw of each relative motion (wheel odometry)
  kFull,    ///< all three translations and rotations
};

/// Noise added to each frame-to-frame motion: Gaussian, zero mean, per axis in the frame of the
/// earlier pose, σ = sigma_fixed + sigma_proportional · |motion|.
struct OdometryNoiseParams {
  double translation_sigma = 0.005;           ///< [m] per frame, per axis
  double translation_sigma_per_metre = 0.02;  ///< [-] extra σ per metre travelled in the frame
  double rotation_sigma = 0.001;              ///< [rad] per frame, per axis
  double rotation_sigma_per_radian = 0.02;    ///< [-] extra σ per radian turned in the frame
  OdometryNoiseAxes axes = OdometryNoiseAxes::kPlanar;
  std::uint64_t seed = 1;
};

/// The relative motions T_{i−1}⁻¹·T_i of `truth`, each perturbed, integrated from truth[0]
/// (so the result starts at the true first pose and drifts). Deterministic for a seed.
[[nodiscard]] PoseList noisy_odometry(const PoseList& truth, const OdometryNoiseParams& params);

/// Stop, move, stop: the sensor rests at each given pose, then moves in a straight line (and a
/// uniform rotation) to the next.
struct StopAndGoParams {
  double stop_duration = 1.0;  ///< [s] at each stop
  double speed = 0.2;          ///< [m/s] between stops
  double turn_rate = 0.5;      ///< [rad/s] bound on the rotation rate between stops
  double frame_rate = 10.0;    ///< [Hz]
};

struct StopAndGo {
  Trajectory trajectory;
  std::vector<std::int32_t> stop;  ///< per frame: index of the stop the sensor rests at, or −1 moving
};
[[nodiscard]] StopAndGo stop_and_go(const PoseList& stops, const StopAndGoParams& params);

}  // namespace hmap::sim
