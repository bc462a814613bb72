#pragma once
// The three degrees of freedom the planar match of eq. (5) does not see: height z, roll and pitch,
// from the scans alone. Two pieces, both on the HVoxels the HMAP already has:
//  - the first scan's gravity from its dominant floor (RANSAC over its thin HVoxels below the
//    sensor), so that a tilted sensor starts level;
//  - after each planar match, a Gauss-Newton fit of (z, roll, pitch) that brings the scan's thin
//    HVoxels (floors, ceilings, table tops, the road) onto the heights of the map's thin HVoxels in
//    the same columns: a point-to-plane alignment restricted to horizontal surfaces, which are
//    exactly what constrains these three.

#include <Eigen/Core>
#include <array>
#include <optional>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/maps/scan_hvoxels.hpp"
#include "hmap/slam/hvoxel_metric.hpp"

namespace hmap::slam {

/// The part of the pose the planar match does not estimate.
struct Attitude {
  double z = 0.0;      ///< [m]
  double roll = 0.0;   ///< [rad] about x
  double pitch = 0.0;  ///< [rad] about y
};

/// What the attitude fit did on one scan.
struct AttitudeFit {
  Attitude attitude;          ///< the estimate (the guess where nothing was observable)
  bool ran = false;           ///< false when the attitude came from outside (--attitude-from, IMU)
  int iterations = 0;
  std::size_t surfaces = 0;   ///< scan HVoxels paired with a map surface at the last iteration
  double rms = 0.0;           ///< [m] RMS height residual of those pairs at the estimate
  /// Information per pair along z, roll and pitch (diagonal of the normal equations / pairs, in
  /// 1, m², m²): a horizontal surface seen only straight ahead constrains pitch, not roll.
  Eigen::Vector3d information = Eigen::Vector3d::Zero();
  /// z, roll, pitch observable (information above the slam.attitude_min_* thresholds); an axis that
  /// is not keeps its guess.
  std::array<bool, 3> observable{false, false, false};
  double yaw_change = 0.0;    ///< [rad] the yaw the fitted tilt implies (second order; add it to the planar yaw)
  /// How well the fitted attitude puts the scan's surfaces on the map's: Σ max(0, 1 − (r / gate)²)
  /// over the pairs of the last iteration (gate: its pairing gate). Compares tilt hypotheses of one
  /// scan (HmapSlam): the right tilt pairs more surfaces, closer.
  double agreement = 0.0;
};

/// The upward unit normal of the scan's dominant floor, in the frame its HVoxels were built in
/// (any rotation; the sensor at `origin_map`). nullopt when no plane below the sensor within
/// slam.max_floor_tilt of that frame's z holds slam.attitude_min_surfaces thin HVoxels.
[[nodiscard]] std::optional<Eigen::Vector3d> floor_normal(const ScanHVoxels& scan, const Params& params);

/// The roll and pitch (z kept from `a`) that turn the sensor-frame vector `n_sensor` into the
/// level-frame vector `target` (both unit; yaw is not touched): the tilt a scan needs for its floor
/// normal to point where the map's floor normal points.
[[nodiscard]] Attitude tilt_aligning(const Eigen::Vector3d& n_sensor, const Eigen::Vector3d& target, const Attitude& a);

/// The sensor → level-frame rotation Ry(pitch)·Rx(roll) of an attitude.
[[nodiscard]] Eigen::Matrix3d level_rotation(const Attitude& a);

/// The (z, roll, pitch) fit against the map. Holds its buffers across scans.
class AttitudeRefiner {
 public:
  explicit AttitudeRefiner(const Params& params);

  /// Refines `guess` for a scan whose HVoxels `scan_level` were built in the gravity-aligned
  /// sensor frame of `guess` (x = y = yaw = 0) and whose planar pose in the map is (x, y, yaw).
  /// The small rotation found is applied about the sensor in that frame.
  /// `floor_level` (this scan's floor normal in that frame, when it has a floor): the fit is pulled
  /// toward the tilt that makes it vertical, with slam.level_prior times the tilt information of
  /// the map pairs. Without it nothing anchors the tilt to gravity: the map agrees with its own
  /// drift (a 1.5° pitch error after a ramp raised a flat street by 4 m over 250 m).
  /// `gravity_level` (an IMU's up direction in that frame): the same pull toward making it
  /// vertical, with slam.imu_tilt_weight times the pairs' tilt information (relative, not from the
  /// pairs' count: their errors are not independent, the rings on a far wall all tilt together).
  /// Where the pairs are too few for an axis the guess (the IMU's tilt) is kept.
  [[nodiscard]] AttitudeFit refine(const ScanHVoxels& scan_level, const HMap& map, double x, double y, double yaw,
                                   const Attitude& guess,
                                   const std::optional<Eigen::Vector3d>& floor_level = std::nullopt,
                                   const std::optional<Eigen::Vector3d>& gravity_level = std::nullopt);

 private:
  struct Sample {
    Eigen::Vector3d p;  // centre of a thin scan HVoxel in the level frame of the guess [m]
    double weight;
  };
  /// A sample's pairing in one iteration: its corrected position and the surface it meets.
  struct Pairing {
    Eigen::Vector3d q;  // relative to the sensor, corrected [m]
    double r;           // height above the nearest thin map surface within the gate [m]
    bool found;
  };
  Params params_;
  std::vector<Sample> samples_;
  std::vector<Pairing> pairings_;
  LocalMapView view_;  // the map's tiles around the scan: one hash lookup per tile, not per sample
};

}  // namespace hmap::slam
