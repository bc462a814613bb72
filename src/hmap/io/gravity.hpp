#pragma once
// Gravity alignment of a recording's world frame: the map frame of hmap has z up, but RGB-D
// trackers (KinectFusion, 7-Scenes, TUM) use the first camera's optical frame, y down. The rotation
// T_map_world comes from the user (an up axis or a rotation matrix) or from the floor plane.

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "hmap/core/types.hpp"

namespace hmap {

/// "x", "+y", "-z" (any case) as a unit vector of the world frame. Throws hmap::Error otherwise.
[[nodiscard]] Eigen::Vector3d parse_up_axis(std::string_view axis);

/// Nine numbers (row-major, separated by commas or spaces) as the rotation T_map_world; it must be
/// orthonormal with determinant +1 within 1e-3. Throws hmap::Error otherwise.
[[nodiscard]] Pose parse_rotation(std::string_view text);

/// The smallest rotation T_map_world taking the world vector `up_world` to +z (yaw is kept as far
/// as a rotation about the axis orthogonal to both allows). `up_world` need not be unit length.
[[nodiscard]] Pose gravity_rotation(const Eigen::Vector3d& up_world);

struct FloorParams {
  double inlier_distance = 0.03;  ///< [m] a point within this of the plane supports it
  int iterations = 400;           ///< RANSAC samples
  double max_tilt = 0.6;          ///< [rad] planes tilted more than this from the prior up are not floors (~34°)
  std::uint32_t seed = 1;         ///< fixed: the same estimate every run
  double min_inlier_fraction = 0.05;  ///< fewer supporting points than this fraction: no floor found
  /// [m] with sensor positions given, a plane farther than this from every one of them is not the
  /// floor under them but a wall or a table top across the room (office1.pcd: a wall 5 m ahead of a
  /// camera that sees no floor). A hand-held camera, a robot or a car roof is within 3 m of its floor.
  double max_sensor_distance = 3.0;
  /// With sensor positions given, a plane counts only where a sensor stands above it (on the side
  /// its normal, turned toward the prior up, points to): a ceiling is not taken for a floor.
  bool below_sensors = false;
};

struct FloorEstimate {
  bool found = false;
  Eigen::Vector3d up_world = Eigen::Vector3d::UnitZ();  ///< floor normal pointing up, unit
  double height = 0.0;            ///< [m] the floor is {p : up_world · p = height}
  std::size_t inliers = 0;
  std::size_t points = 0;
};

/// The dominant floor: the plane with the most points within `inlier_distance` among those whose
/// normal is within `max_tilt` of `prior_up_world` (for a hand-held or robot camera, the mean of
/// the cameras' up vectors −y_cam) and, when `sensors_world` is not empty, that lie within
/// `max_sensor_distance` of one of the sensors; refined by least squares over its supporting points.
[[nodiscard]] FloorEstimate estimate_floor(std::span<const Point3f> points_world, const Eigen::Vector3d& prior_up_world,
                                           const FloorParams& params = {},
                                           std::span<const Eigen::Vector3d> sensors_world = {});

/// A floor is seen from above. When every sensor position lies below the estimated plane and its
/// normal is more than `min_tilt` [rad] from the prior up, the prior chose the wrong side: the
/// normal and height are flipped (the PCL grabber frames of a Kinect pitched 42° down at the floor,
/// read with a scanner's +z as the prior, came out upside down and gave no ground). A plane within
/// `min_tilt` of the prior with the sensors below it is a ceiling under a sound prior: kept.
/// Returns whether it flipped.
bool orient_floor_below_sensors(FloorEstimate& floor, std::span<const Eigen::Vector3d> sensors_world,
                                const Eigen::Vector3d& prior_up_world, double min_tilt = 0.35);

/// The floor under a sensor, from one of its scans in the sensor's own frame: estimate_floor with
/// the sensor at the origin, above the plane and within params.max_sensor_distance of it
/// (below_sensors is set). `prior_up_sensor` is the sensor's up as mounted: −y for a
/// depth camera's optical frame, +z for a spinning LiDAR. Not found (std::nullopt) when no plane
/// within params.max_tilt of the prior holds params.min_inlier_fraction of the points.
struct SensorFloor {
  Eigen::Vector3d up_sensor = Eigen::Vector3d::UnitZ();  ///< the floor's normal, pointing up, unit
  double sensor_height = 0.0;  ///< [m] the sensor above the floor, along up_sensor
  std::size_t inliers = 0;
  std::size_t points = 0;
};
[[nodiscard]] std::optional<SensorFloor> floor_under_sensor(std::span<const Point3f> points_sensor,
                                                            const Eigen::Vector3d& prior_up_sensor,
                                                            const FloorParams& params = {});

}  // namespace hmap
