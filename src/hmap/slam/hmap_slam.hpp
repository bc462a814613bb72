#pragma once
// SLAM on the HMAP (section IV-C, Fig. 2, red): each scan is matched against the map by
// Gauss-Newton over ξ = (x, y, yaw), then merged into the map at the estimated pose.

#include <optional>
#include <span>

#include "hmap/maps/mapper.hpp"
#include "hmap/slam/attitude.hpp"
#include "hmap/slam/deskew.hpp"
#include "hmap/slam/imu.hpp"
#include "hmap/slam/map_align.hpp"
#include "hmap/slam/scan_matcher.hpp"
#include "hmap/slam/wall_refiner.hpp"

namespace hmap::slam {

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

/// One scan and what else is known about it.
struct ScanInput {
  std::span<const Point3f> points_sensor;
  /// [s] per point, from the scan's reference time (the time its pose is for); empty: no time.
  std::span<const float> times;
  /// [s] the scan's stamp (for the velocity of the deskewing); nullopt: the sweep's time span is
  /// taken as the scan period (a spinning lidar sweeps once per scan).
  std::optional<double> stamp;
  std::optional<Attitude> attitude;  ///< z, roll, pitch given (reference poses): taken as they are
  std::optional<PlanarPose> guess;   ///< x, y, yaw guess (odometry); nullopt: constant velocity
  std::optional<ImuPrior> imu;       ///< the IMU's gravity and rotation since the previous scan
};

/// Where a continued map's first scan is looked for (HmapSlam's continuing constructor).
struct ContinueOptions {
  PlanarPose guess;                 ///< where the first scan is believed to lie in the saved map (x, y, yaw)
  double search_translation = 5.0;  ///< [m] half-width of its coarse search in x and y, [0, 20]
  double search_rotation = 3.14159265358979323846;  ///< [rad] half-width in yaw, [0, π]: all headings by default
};

/// What one SLAM step did.
struct SlamStep {
  Pose T_map_sensor = Pose::Identity();  ///< the sensor's pose at the scan's reference time (its stamp)
  /// The pose the scan was matched and merged at: T_map_sensor, or, when deskewed with the last
  /// estimates' velocity, the pose at the sweep's middle (`merged_at_s` on the points' clock).
  Pose T_map_merged = Pose::Identity();
  double merged_at_s = 0.0;  ///< [s] the time of T_map_merged on the points' clock (0: the reference)
  PlanarPose guess;                      ///< the prediction matching started from
  bool matched = false;                  ///< false for the first scan (it defines the map frame)
  MatchResult match;
  AttitudeFit attitude;                  ///< the z / roll / pitch fit (attitude.ran false when given)
  /// The sub-cell refinement of x, y and yaw against the map's walls, after the planar match
  /// (walls.applied false: not run, or not taken; walls.skipped_because says which).
  WallRefinement walls;
  int planar_passes = 0;                 ///< planar matches run (a second after a large attitude change)
  /// Which of x, y, z, roll, pitch, yaw the scan constrained (the planar match's curvature for x,
  /// y, yaw; the attitude fit's information for z, roll, pitch). All false for the first scan and
  /// for a skipped match; z, roll, pitch false when the attitude was given.
  std::array<bool, 6> observable{false, false, false, false, false, false};
  ScanStats mapping;
  bool deskewed = false;       ///< the points were moved to one time (merged_at_s)
  Twist sweep_velocity;        ///< the velocity they were moved with
  bool imu_used = false;       ///< an IMU prior shaped the tilt and the rotation guess
  /// Tilt hypotheses compared against the map (2: the floor's prediction and the last tilt
  /// differed; 0 or 1: there was one) and whether the floor's won.
  int tilt_hypotheses = 0;
  bool tilt_from_floor = true;
  double wall_tilt = 0.0;            ///< [rad] the tilt the walls' lean corrected (slam.wall_tilt_drift)
  std::size_t wall_tilt_walls = 0;   ///< the walls it was measured on
  /// The first scan of a continued map: where it was found in the saved map (align_maps of the
  /// levelled scan onto the map, before the planar match refined it). Empty otherwise.
  std::optional<MapAlignResult> relocalised;
};

/// The scan-to-map SLAM loop. Not thread-safe; one instance per sequence.
class HmapSlam {
 public:
  /// Throws hmap::Error for invalid parameters.
  explicit HmapSlam(const Params& params);
  /// Continues `map` (a saved HMAP): scans are matched against it and merged into it. The map keeps
  /// its own map parameters (cell, ranges, layers: a map built on with others would not be one map);
  /// `params` gives the rest (slam.*). The first scan, levelled by its floor, is registered onto the
  /// map by align_maps (a coarse search of `where`'s window about its guess, z from the floors),
  /// then matched as every later scan is; with a constant-velocity start from there. Throws
  /// hmap::Error for an empty map, invalid parameters or a search window out of range; process()
  /// throws when the first scan has no column over the map at the guess. `centroids`: the map's
  /// cell centroids as saved with it (MapFile::centroids; slam.hvoxel_centroids 2), else the
  /// continued session starts without them; their cell must be the map's.
  HmapSlam(const Params& params, HMap map, const ContinueOptions& where, std::optional<CellCentroids> centroids = std::nullopt);

  /// Matches `points_sensor` against the map from `guess` (nothing: constant velocity from the
  /// last two estimates), then integrates it at the estimate. The first scan is integrated at
  /// the guess (identity by default).
  /// `attitude` given (an IMU, reference poses): z, roll and pitch are taken as they are. Not given:
  /// they are estimated from the scans: the first scan's tilt levels its floor (floor_normal; the
  /// map's z is that floor's normal); every later scan's tilt is first predicted by turning its
  /// floor normal onto the map's floor normal last seen (a handheld sensor tilts by 15° between
  /// scans, more than the map fit can pair), then z, roll and pitch are fitted to the map's
  /// horizontal surfaces by AttitudeRefiner after the planar match, and the planar match repeated
  /// once when that moved the attitude by more than a little.
  SlamStep process(std::span<const Point3f> points_sensor, const std::optional<Attitude>& attitude,
                   const std::optional<PlanarPose>& guess = std::nullopt);

  /// The same with what else is known. With `imu` (and no attitude given): the tilt guess is the
  /// IMU's gravity (not the floor's), the yaw guess turns by the gyro's rotation since the last
  /// scan, and the attitude fit is pulled toward the IMU's gravity (slam.imu_tilt_weight times the
  /// map pairs' tilt information) instead of toward a level floor; where the scan
  /// has too few horizontal surfaces for an axis, the IMU's value stands. With `times` (and
  /// slam.deskew): the points are first moved to one time by the constant body velocity: to the
  /// reference time with odometry's velocity (the guess), to the sweep's middle with the last two
  /// estimates' (its rotation from the IMU's rate when there is one), so that an error in that
  /// velocity skews the scan about its middle and does not move the matched pose (fed back, it
  /// would: docs/SLAM.md). The pose at the reference time is then that at the middle moved back
  /// by the same velocity.
  SlamStep process(const ScanInput& input);

  /// The height the first scan is put at when its attitude is estimated (default 0: the map frame
  /// starts at the sensor). Call before the first process().
  void start_at_height(double z) { last_attitude_.z = z; }

  /// The first scan's tilt guess when its attitude is estimated: the roll and pitch that turn
  /// `up_sensor` (gravity's up in the sensor frame, e.g. a floor normal found in the first scan) to
  /// the map's +z. Without it the first scan is taken as level, and its floor is looked for within
  /// slam.max_floor_tilt of that: a depth camera's optical frame (y down) is 90° from it. The
  /// first scan's own floor then refines the tilt as for any scan. Call before the first process().
  /// Throws hmap::Error for a zero or non-finite vector.
  void start_with_up(const Eigen::Vector3d& up_sensor);
  /// The attitude the first scan starts from (start_at_height, start_with_up), before any scan.
  [[nodiscard]] const Attitude& first_attitude() const { return last_attitude_; }

  /// The body velocity of the last two estimates (their stamps' difference, or the last sweep's
  /// span); zero before two scans or without stamps and times. For ImuAttitudeFilter::set_body_velocity.
  [[nodiscard]] Twist velocity() const;

  /// The constant-velocity prediction for the next scan: last ⊕ (previous⁻¹ ⊕ last).
  [[nodiscard]] PlanarPose predict() const;

  [[nodiscard]] const HMap& map() const { return mapper_.map(); }
  /// Where in its cell the map's surface lies (slam.hvoxel_centroids 2; empty otherwise): for
  /// saving with the map (save_hmap) while map_holds_scans_as_given or the map was not rebuilt.
  [[nodiscard]] const CellCentroids& map_centroids() const { return map_centroids_; }
  /// The parameters in force (a continued map's own map parameters with the given slam.*).
  [[nodiscard]] const Params& params() const { return params_; }
  [[nodiscard]] std::size_t scans() const { return scans_; }
  /// True while the map is exactly the scans given to process(), as given, integrated in order at
  /// their T_map_sensor (Mapper::integrate): no scan was merged deskewed or at another pose, and
  /// no saved map was continued. Then a loop closure may rebuild only the tiles its corrections
  /// reach (slam::map_at_corrected_poses), else all of the map.
  [[nodiscard]] bool map_holds_scans_as_given() const { return map_as_given_; }

 private:
  [[nodiscard]] Twist velocity_between(double dt) const;

  Params params_;
  Mapper mapper_;
  ScanMatcher matcher_;
  AttitudeRefiner refiner_;
  Attitude last_attitude_;
  Eigen::Vector3d floor_up_ = Eigen::Vector3d::UnitZ();  // the floor's upward normal in the map, last seen
  // The tilt's error variance (dx/dz, dy/dz of the verticals in the level frame) for the walls'
  // correction: wide before the first scan (a first floor may slope), grown per scan, shrunk by walls.
  Eigen::Matrix2d tilt_variance_ = Eigen::Matrix2d::Identity() * 0.05 * 0.05;
  ScanHVoxelizer level_hvoxelizer_;
  ScanHVoxels scan_level_;
  CellCentroids map_centroids_;  // slam.hvoxel_centroids 2: where in its cell the map's surface lies
  WallRefiner wall_refiner_;
  WallGrid wall_map_;     // the map's wall points' moments (map frame)
  WallGrid wall_scan_;    // this scan's (level frame)
  std::vector<Eigen::Vector3d> wall_points_;
  PlanarPose last_;
  PlanarPose previous_;
  Eigen::Matrix3d pose_covariance_ = Eigen::Matrix3d::Zero();  // of last_ (m, m, rad), with odometry
  // The last two full estimates as merged (at the sweep's middle when deskewed with the
  // estimates' velocity), for the sweep's velocity.
  Pose T_last_ = Pose::Identity();
  Pose T_previous_ = Pose::Identity();
  double merged_at_last_ = 0.0;      // [s] their times after their stamps (SlamStep::merged_at_s)
  double merged_at_previous_ = 0.0;
  std::optional<double> stamp_last_;
  std::optional<double> stamp_previous_;
  double last_sweep_ = 0.0;             // [s] time span of the last scan's points
  PointCloud deskewed_;
  // The first scans, integrated without a velocity to deskew them with, kept (at most
  // kMaxSkewedScans, and only while every scan so far is one) until a velocity is known.
  struct SkewedScan {
    PointCloud points;
    std::vector<float> times;
    Pose T_map_sensor;
  };
  static constexpr std::size_t kMaxSkewedScans = 2;
  std::vector<SkewedScan> skewed_;
  std::size_t scans_ = 0;
  std::optional<ContinueOptions> continuing_;  // set: the map was saved before; the first scan is found in it
  bool map_as_given_ = true;  // map_holds_scans_as_given()
};

}  // namespace hmap::slam
