#pragma once
// SLAM on the HMAP (section IV-C, Fig. 2, red): each scan is matched against the map by
// Gauss-Newton over ξ = (x, y, yaw), then merged into the map at the estimated pose.

#include <optional>
#include <span>

#include "hmap/maps/mapper.hpp"
#include "hmap/slam/scan_matcher.hpp"

namespace hmap::slam {

/// The part of the pose SLAM does not estimate: height and tilt, from an IMU-like source or zero.
struct Attitude {
  double z = 0.0;      ///< [m]
  double roll = 0.0;   ///< [rad] about x
  double pitch = 0.0;  ///< [rad] about y
};

/// z, roll and pitch of a pose, with R = Rz(yaw)·Ry(pitch)·Rx(roll).
[[nodiscard]] Attitude attitude_of(const Pose& T);
/// x, y and yaw of a pose (yaw of the same decomposition).
[[nodiscard]] PlanarPose planar_of(const Pose& T);
/// The SE(3) pose Trans(x, y, z)·Rz(yaw)·Ry(pitch)·Rx(roll).
[[nodiscard]] Pose compose(const PlanarPose& xi, const Attitude& attitude);
/// a ⊕ b in SE(2): b expressed in a's frame.
[[nodiscard]] PlanarPose operator*(const PlanarPose& a, const PlanarPose& b);
/// The inverse in SE(2).
[[nodiscard]] PlanarPose inverse(const PlanarPose& a);

/// What one SLAM step did.
struct SlamStep {
  Pose T_map_sensor = Pose::Identity();  ///< the pose the scan was merged at
  PlanarPose guess;                      ///< the prediction matching started from
  bool matched = false;                  ///< false for the first scan (it defines the map frame)
  MatchResult match;
  ScanStats mapping;
};

/// The scan-to-map SLAM loop. Not thread-safe; one instance per sequence.
class HmapSlam {
 public:
  /// Throws hmap::Error for invalid parameters.
  explicit HmapSlam(const Params& params);

  /// Matches `points_sensor` against the map from `guess` (nothing: constant velocity from the
  /// last two estimates), then integrates it at the estimate. The first scan is integrated at
  /// the guess (identity by default).
  SlamStep process(std::span<const Point3f> points_sensor, const Attitude& attitude,
                   const std::optional<PlanarPose>& guess = std::nullopt);

  /// The constant-velocity prediction for the next scan: last ⊕ (previous⁻¹ ⊕ last).
  [[nodiscard]] PlanarPose predict() const;

  [[nodiscard]] const HMap& map() const { return mapper_.map(); }
  [[nodiscard]] std::size_t scans() const { return scans_; }

 private:
  Params params_;
  Mapper mapper_;
  ScanMatcher matcher_;
  ScanHVoxelizer level_hvoxelizer_;
  ScanHVoxels scan_level_;
  PlanarPose last_;
  PlanarPose previous_;
  std::size_t scans_ = 0;
};

}  // namespace hmap::slam
