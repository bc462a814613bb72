#pragma once
// Simulated range sensors. Each is configured by a parameter struct (units in the comments, the
// real device as a preset), owns a std::mt19937_64 seeded from that struct, and returns its
// points in the sensor frame: x forward, y left, z up. The same parameters and the same sequence
// of calls give the same points.
//
// Noise models (all noise is along the beam; directions are exact):
//   spinning lidar   range + N(0, range_sigma²); each return dropped with dropout_probability
//   depth camera     depth (along the optical axis) + N(0, σ(d)²) with
//                    σ(d) = sigma_base + sigma_quadratic·(d − sigma_offset)² (Kinect v2 axial noise)
//   line scanner     range + N(0, range_sigma²); dropouts as the spinning lidar
// A return is kept when its measured range (depth for the camera) lies in [min_range, max_range].

#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "hmap/core/types.hpp"
#include "hmap/sim/scene.hpp"

namespace hmap::sim {

/// The points of one simulated scan with, per point, what produced it, and counts of the rays.
struct SimulatedScan {
  PointCloud points_sensor;               ///< [m] sensor frame
  std::vector<std::uint16_t> channel;     ///< ring (lidars), image row (camera), sweep step (line scanner)
  std::vector<std::uint32_t> primitive;   ///< the solid hit
  std::vector<SurfaceKind> kind;          ///< what that solid stands for
  std::vector<float> time;                ///< [s] per point from the sweep's start (SpinningLidar::sweep only)
  std::size_t rays = 0;                   ///< rays cast
  std::size_t no_return = 0;              ///< rays that hit nothing within max_range
  std::size_t out_of_range = 0;           ///< returns whose measured range left [min_range, max_range]
  std::size_t dropped = 0;                ///< returns lost to random dropouts
};

/// A multi-beam spinning lidar: one ring per elevation angle, one column per azimuth step over
/// 360°. The whole frame is taken at one time (no motion during the sweep).
struct SpinningLidarParams {
  std::vector<double> elevations_deg;   ///< [deg] beam elevation, one per ring, in ring order
  double azimuth_step_deg = 0.2;        ///< [deg] between columns
  double min_range = 0.5;               ///< [m]
  double max_range = 100.0;             ///< [m]
  double range_sigma = 0.03;            ///< [m] σ of the Gaussian range noise
  double dropout_probability = 0.005;   ///< [-] chance that a return is lost
  std::uint64_t seed = 1;               ///< noise seed
  double sweep_period = 0.1;            ///< [s] one revolution (sweep(); 10 Hz)

  /// Velodyne VLP-16: 16 rings −15°..+15° every 2°, 0.2° azimuth (10 Hz), 0.5–100 m, σ 3 cm, 0.5 % dropouts.
  [[nodiscard]] static SpinningLidarParams vlp16();
  /// Velodyne HDL-64E: upper block +2° to −8.33° in 1/3° steps, lower block −8.83° to −24.33° in
  /// 1/2° steps, 0.17° azimuth, 0.9–120 m, σ 2 cm, 0.5 % dropouts.
  [[nodiscard]] static SpinningLidarParams hdl64e();
  /// Ouster OS0-64 (the sensor of ../shared/data/balm_os0): 64 rings evenly over −45°..+45°
  /// (1.43° apart), 1024 columns (0.35° azimuth, 10 Hz), 0.3–50 m, σ 1.5 cm, 0.5 % dropouts.
  [[nodiscard]] static SpinningLidarParams os0_64();
};

class SpinningLidar {
 public:
  /// Throws hmap::Error for no rings, a non-positive step or range, or a probability outside [0, 1].
  explicit SpinningLidar(SpinningLidarParams params);
  /// One full revolution at time `t_seconds`, the sensor at T_world_sensor. Points come column by
  /// column (azimuth from 0° counter-clockwise), rings in the order of elevations_deg.
  [[nodiscard]] SimulatedScan scan(const Scene& scene, const Pose& T_world_sensor, double t_seconds);
  /// One revolution while the sensor moves (what a real spinning lidar gives): column c fires at
  /// t0 + c / columns · sweep_period with the sensor at T_world_sensor_at(that time); its points are
  /// in the sensor frame of that moment and carry their time from t0 in `time`.
  [[nodiscard]] SimulatedScan sweep(const Scene& scene, const std::function<Pose(double)>& T_world_sensor_at,
                                    double t0);
  [[nodiscard]] const SpinningLidarParams& params() const { return params_; }

 private:
  SpinningLidarParams params_;
  std::vector<Eigen::Vector3d> directions_sensor_;  ///< unit beam directions, column-major
  std::mt19937_64 rng_;
};

/// A time-of-flight depth camera (pinhole, square pixels not assumed).
struct DepthCameraParams {
  int width = 512;                      ///< [px]
  int height = 424;                     ///< [px]
  double horizontal_fov_deg = 70.6;     ///< [deg]
  double vertical_fov_deg = 60.0;       ///< [deg]
  double min_range = 0.5;               ///< [m] on depth
  double max_range = 4.5;               ///< [m] on depth
  double sigma_base = 0.0012;           ///< [m]   σ(d) = base + quadratic·(d − offset)²
  double sigma_quadratic = 0.0019;      ///< [1/m]
  double sigma_offset = 0.4;            ///< [m]
  double dropout_probability = 0.0;     ///< [-]
  std::uint64_t seed = 1;

  /// Kinect One (v2) depth: 512 × 424, 70.6° × 60°, 0.5–4.5 m, axial noise of Nguyen et al. 2012.
  [[nodiscard]] static DepthCameraParams kinect_one() { return {}; }
};

class DepthCamera {
 public:
  explicit DepthCamera(DepthCameraParams params);
  /// One depth image turned into points (sensor frame, x forward), row by row from the top; the
  /// channel of a point is its image row.
  [[nodiscard]] SimulatedScan scan(const Scene& scene, const Pose& T_world_sensor, double t_seconds);
  [[nodiscard]] const DepthCameraParams& params() const { return params_; }

 private:
  DepthCameraParams params_;
  std::vector<Eigen::Vector3d> rays_sensor_;  ///< per pixel, scaled so that the x (depth) component is 1
  std::mt19937_64 rng_;
};

/// How a 2D line scanner is swept to make a 3D scan.
enum class SweepMode : std::uint8_t {
  kTilt,  ///< scan plane horizontal at angle 0; the unit pitches it about the sensor's y axis
  kYaw,   ///< scan plane vertical (containing x and z); the unit turns it about the vertical axis
};

/// A 2D line scanner (scan plane angle −fov/2..fov/2 about its own rotation axis) on a sweeping unit.
struct LineScannerParams {
  double field_of_view_deg = 270.0;     ///< [deg]
  double angular_step_deg = 0.25;       ///< [deg]
  double min_range = 0.1;               ///< [m]
  double max_range = 30.0;              ///< [m]
  double range_sigma = 0.01;            ///< [m]
  double dropout_probability = 0.0;     ///< [-]
  SweepMode sweep = SweepMode::kTilt;
  double sweep_min_deg = -45.0;         ///< [deg] first pitch (kTilt, positive looks down) or yaw (kYaw)
  double sweep_max_deg = 45.0;          ///< [deg] last sweep angle
  int sweep_steps = 91;                 ///< line scans per 3D scan, from min to max inclusive
  double line_period = 0.025;           ///< [s] between line scans (UTM-30LX: 40 Hz)
  std::uint64_t seed = 1;

  /// Hokuyo UTM-30LX (270° at 0.25°, used 0.1–30 m, σ 10 mm) on a tilting unit, −45°..+45° in 1° steps.
  [[nodiscard]] static LineScannerParams utm30lx_tilting() { return {}; }
  /// The same scanner turning about the vertical axis, its scan plane vertical, 0°..180° in 1° steps.
  [[nodiscard]] static LineScannerParams utm30lx_yawing();
};

class LineScanner {
 public:
  explicit LineScanner(LineScannerParams params);
  /// One sweep: line scan k is taken at time t_seconds + k·line_period with the unit at step k.
  /// Points are in the frame of the unit's base (the sensor frame at sweep angle 0).
  [[nodiscard]] SimulatedScan scan(const Scene& scene, const Pose& T_world_sensor, double t_seconds);
  [[nodiscard]] const LineScannerParams& params() const { return params_; }

 private:
  LineScannerParams params_;
  std::vector<Eigen::Vector3d> directions_base_;  ///< per (step, beam), step-major
  std::mt19937_64 rng_;
};

}  // namespace hmap::sim
