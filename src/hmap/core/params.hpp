#pragma once
// Every parameter of hmap, with its unit and default, and the presets of the paper's section V.
//
// Defaults equal the `outdoor` preset. Parameters are reachable by name (for config files and
// command-line overrides) through `for_each_param`.

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace hmap {

/// How free space is computed when a scan is integrated.
enum class FreeSpaceMode : std::uint8_t {
  kRayTracing = 0,  ///< Alg. 3: free HVoxels along the 2D traversal, then extrusion (III-E).
  kNone = 1,        ///< Occupied HVoxels only: merging without extrusion.
};

/// The HMAP itself: indexing, clustering, density, free space, merging, extrusion (section III).
struct MapParams {
  double cell_size = 0.25;                 ///< [m] edge of a square grid cell
  double point_distance_threshold = 0.4;   ///< [m] gap on z that splits a height cluster (Alg. 2)
  double ring_gap_slope = 0.0;             ///< [m/m] the gap grows by this per metre of a cell's distance
                                           ///< from the sensor (a spinning LiDAR's rings on a wall spread
                                           ///< with range); 0: point_distance_threshold everywhere
  double ring_gap_max = 3.0;               ///< [m] the most ring_gap_slope widens the gap to (a storey: a
                                           ///< wall two rings that far apart hit stays one HVoxel)
  double min_range = 1.2;                  ///< [m] points closer to the sensor are dropped
  double max_range = 25.0;                 ///< [m] points farther from the sensor are dropped
  double density_gain = 1.0;               ///< K_m, eq. (1) amplitude gain [-]
  double density_normalization = 0.0005;   ///< K_n, eq. (1) sample normalisation [m^3]
  double density_min_points = 5.0;         ///< d_min, eq. (1) minimum number of points [-]
  double min_hvoxel_height = 0.25;         ///< [m] floor of h in V = h·A of eq. (1): one point has h = 0
  double density_threshold = 0.5;          ///< n_th [-]: ray casting, extrusion removal, SLAM selection;
                                           ///< 0.5 means |v| >= d_min, whatever the volume
  FreeSpaceMode free_space = FreeSpaceMode::kRayTracing;
  double free_unite_gap = 0.05;            ///< [m] free bands of one cell closer than this unite:
                                           ///< neighbouring rays leave slivers a few cm apart
};

/// Ground extraction by RRT patch exploration (section IV-A, Alg. 4).
struct GroundParams {
  int iterations = 400;                    ///< K [-]
  double normal_threshold = 0.2;           ///< N_th [-]: patches connect when 1 − |n1·n2| <= N_th
  double elevation_threshold = 0.2;        ///< E_th [m]
  double expansion_distance = 0.9;         ///< d_n [m]
  double top_noise = 0.02;                 ///< [m] σ of the HVoxel tops on a flat floor (the paper's
                                           ///< σ): a patch's RMS may exceed E_th / 4 by this, in quadrature
  std::uint64_t seed = 1;                  ///< RNG seed: same seed, same patches
};

/// 2D occupancy kept alongside the HMAP (section IV-B, eq. 3-4).
struct OccupancyParams {
  double sigma = 0.02;                     ///< σ of the obstacle term of eq. (4) [m]
  double ground_gain = 0.3;                ///< K_g in [0, 0.5] [-]
  double ground_distance = 0.1;            ///< d_pth [m]
  double z_plus = 2.0;                     ///< z+ [m] above the local ground: higher HVoxels ignored
  double z_minus = -0.5;                   ///< z− [m] below the local ground: lower HVoxels ignored
  double clamp_min = 0.12;                 ///< [-] probability floor (OctoMap's default clamping)
  double clamp_max = 0.97;                 ///< [-] probability ceiling
  double ground_reach = 3.0;               ///< [m] HVoxels farther than this beyond the square of
                                           ///< their nearest ground patch are not judged
  double obstacle_reach = 15.0;            ///< [m] the grid judged from a map: a column farther than
                                           ///< ground_reach from every patch but within this of one is
                                           ///< blocked when its lowest HVoxel stands on that patch's plane
                                           ///< (within ground.elevation_threshold) and rises above d_pth
  double free_ray_height = 0.2;            ///< [m] a ray frees the cells it crosses at most this high above
                                           ///< the ground (2·d_pth: no obstacle that blocks stands there);
                                           ///< above z+ every crossed cell, as the paper's 2D ray
};

/// SLAM by Gauss-Newton matching on the HMAP (section IV-C, eq. 5-12).
struct SlamParams {
  int interpolation_window = 3;            ///< [cells] IDW window of eq. (12)
  double idw_power = 2.0;                  ///< p of eq. (12) [-]
  int max_iterations = 30;                 ///< Gauss-Newton iterations per scan [-]
  double idw_weight = 0.5;                 ///< [-] an IDW-interpolated neighbour (eq. 12) counts this
                                           ///< much of a measured one, so M_H keeps falling off a surface
  double min_match_height = 0.3;           ///< [m] thinner scan HVoxels (floors, ceilings) do not take part:
                                           ///< in the plane they only show the rings' pattern, which
                                           ///< moves with the sensor and pulls the match back; 0 = all
  double min_layer_height = 0.2;           ///< [m] shorter intervals are widened to this for eq. (9)
  double robust_scale = 0.0;               ///< [-] Cauchy scale on 1 − M_H (moving objects); 0 = off
  double convergence_translation = 0.001;  ///< [m] a smaller step ends Gauss-Newton
  double convergence_rotation = 0.0001;    ///< [rad] a smaller step ends Gauss-Newton
  double degeneracy_ratio = 0.1;           ///< [-] smallest / largest curvature of eq. (5) along the
                                           ///< Hessian's eigenvectors under which a match is degenerate
  int max_hvoxels = 0;                     ///< [-] HVoxels matched per scan at most (thinned evenly); 0 = all
  double coarse_trigger_ratio = 0.85;      ///< [-] a match that does not converge, or whose mean M_H falls
                                           ///< under this times the running mean, is retried by a coarse
                                           ///< search; 0 = never
  double coarse_translation = 0.5;         ///< [m] half-width of the coarse search in x and y
  double coarse_rotation = 0.5;            ///< [rad] half-width of the coarse search in yaw
  // Odometry as a motion prior of the planar match (when the scans come with odometry): each
  // scan-to-scan motion is trusted to σ = sigma + noise · |motion|, per axis.
  double odometry_sigma_translation = 0.02;  ///< [m] fixed part of σ in x and y, per scan
  double odometry_sigma_rotation = 0.005;    ///< [rad] fixed part of σ in yaw, per scan
  double odometry_noise = 0.05;              ///< [-] σ added per metre travelled and per radian
                                             ///< turned (wheel odometry: 1-5 %)
  int hvoxel_centroids = 2;                ///< [-] 2 (default): scan HVoxels are matched at their points' plan
                                           ///< centroids and the map's cells read at the centroids of the tall
                                           ///< points merged into them (docs/SLAM.md, "Session 28" and
                                           ///< "Session 29"); 1: the scan's only (the map's still at its
                                           ///< cells' centres: biased where a wall is parallel to the grid);
                                           ///< 0: at their cells' centres, as eq. (6) has it (the match leans
                                           ///< toward poses where the scan's grid and the map's coincide)
  // Sub-cell refinement of x, y and yaw against the map's walls (slam/wall_refiner.hpp).
  int wall_refine = 0;                     ///< [-] 1: after the planar match, x, y and yaw are refined against
                                           ///< the lines of the map's tall HVoxels' points; 0: off (the
                                           ///< default: it halves balm_os0's error but biases a car's
                                           ///< distance on kitti_hdl64_seq16, docs/SLAM.md "Walls")
  double wall_min_height = 0.5;            ///< [m] points of HVoxels at least this tall count as walls
  double wall_band_height = 0.5;           ///< [m] the walls' moments are kept per height band this tall
  int wall_iterations = 6;                 ///< [-] Gauss-Newton iterations of the wall refinement
  double wall_min_pairs = 30;              ///< [-] fewer scan cells paired with a map line: the pose is kept
  double wall_max_rotation = 0.02;         ///< [rad] a refinement turning farther than this (~1.1°) is not taken
  // z, roll and pitch from the scans (slam/attitude.hpp), when no attitude is given.
  double wall_tilt_drift = 0.0002;         ///< [rad] per scan: how far the tilt taken from the floors may
                                           ///< wander from one scan to the next (0.01°); the walls' lean (built
                                           ///< plumb within about 0.2 %) corrects it by a Kalman gain. Without
                                           ///< it a tilt the map fit picks up stays, and z climbs along it
                                           ///< (the 0.3 km towns 1.2-2.9 m; docs/SLAM.md, "Session 37").
                                           ///< 0 = off, the floors alone
  double surface_max_height = 0.3;         ///< [m] HVoxels at most this tall (scan and map) count as horizontal
                                           ///< surfaces for the attitude fit
  double attitude_gate = 0.5;              ///< [m] farthest a scan surface may be from the map's to be paired,
                                           ///< at the first iteration (it shrinks to a third)
  int attitude_iterations = 8;             ///< [-] Gauss-Newton iterations of the attitude fit
  double attitude_min_surfaces = 30;       ///< [-] fewer pairs: the attitude keeps its guess
  double attitude_min_lever = 1.0;         ///< [m] RMS lever arm along x (pitch) or y (roll) under which
                                           ///< that tilt is not observable and keeps its guess
  double level_prior = 0.02;               ///< [-] pull of the attitude fit toward a level floor, as a fraction
                                           ///< of the map's tilt information (0 = the map alone)
  double level_max_slope = 0.07;           ///< [rad] a scan floor the estimate tilts more than this (~4°) is
                                           ///< a slope (ramp), not a level floor: level_prior does not pull it
  double max_floor_tilt = 0.35;            ///< [rad] steepest plane taken for a scan's floor (~20°)
  // The IMU prior (slam/imu.hpp), when the recording has an IMU.
  double imu_gravity_time_constant = 1.0;  ///< [s] τ of the complementary filter: the accelerometer's
                                           ///< gravity corrects the gyro's tilt with gain dt / (τ + dt)
  double imu_accel_gate = 0.2;             ///< [-] samples whose |accel| differs from g by more than this
                                           ///< fraction of g do not correct the tilt (the sensor accelerates)
  double imu_tilt_weight = 0.0;            ///< [-] pull of the attitude fit toward the IMU's gravity, as a
                                           ///< fraction of the map pairs' tilt information (1: as much);
                                           ///< 0 = the IMU's tilt is not used (a vehicle's speed changes
                                           ///< bias it), only its gyro
  double imu_roll = 0.0;                   ///< [rad] R_sensor_imu = Rz(yaw)·Ry(pitch)·Rx(roll): the IMU's
  double imu_pitch = 0.0;                  ///< [rad]   mounting in the sensor frame (identity by default)
  double imu_yaw = 0.0;                    ///< [rad]
  // Per-point time (slam/deskew.hpp).
  int deskew = 1;                          ///< [-] 1: points carrying a time are moved to one time by constant
                                           ///< velocity: odometry's (or an IMU's) to the scan's reference time,
                                           ///< else the last two estimates' to the sweep's middle (docs/SLAM.md);
                                           ///< 0: off
  // Loop closure (slam/loop_closure.hpp, docs/SLAM.md "Loop closure"): key frames, place
  // recognition on their sub-maps, verification by map alignment, a pose graph, the map rebuilt.
  int loop_closure = 1;                    ///< [-] 1: on (hmap slam; --no-loop-closure: 0), 0: off
  double keyframe_distance = 5.0;          ///< [m] a key frame every this far along the estimated path
  double keyframe_rotation = 0.5;          ///< [rad] or after turning this much since the last one
  int loop_submap_scans = 5;               ///< [-] scans merged into a key frame's sub-map at most (it and the next ones)
  double loop_min_travel = 50.0;           ///< [m] a candidate is at least this far back along the path
  double loop_search_radius = 30.0;        ///< [m] and at most this far from the drifted estimate
  double loop_max_descriptor_distance = 0.3;  ///< [-] place descriptors farther apart (0 same, 1 unlike) are no candidate
  int loop_candidates = 3;                 ///< [-] the nearest candidates verified per key frame at most
  double loop_search_translation = 4.0;    ///< [m] half-width of the verification's coarse search in x and y
  double loop_search_rotation = 0.2;       ///< [rad] half-width of its coarse search in yaw about the descriptor's yaw
  double loop_min_score = 0.4;             ///< [-] mean M_H of the verification under which a candidate is refused
};

/// All parameters together.
struct Params {
  MapParams map;
  GroundParams ground;
  OccupancyParams occupancy;
  SlamParams slam;
};

/// Paper section V, indoor (Kinect One, office): 5 cm cells, 0.8-5 m range.
[[nodiscard]] Params indoor_preset();
/// Paper section V, outdoor (VLP-16, campus): 25 cm cells, 1.2-25 m range. Equal to `Params{}`.
[[nodiscard]] Params outdoor_preset();
/// Between the two, for a LiDAR inside a building: the outdoor preset at 10 cm cells and a 10 m
/// range, so that the cell is 1 % of the range as in both of the paper's (0.05 / 5 m, 0.25 / 25 m).
/// In rooms the structure a scan is matched on stands within a few metres, where a 0.25 m cell is
/// 0.06-0.08 rad of yaw (docs/SLAM.md, "Session 33"). Chosen from a first scan, a LiDAR keeps the
/// outdoor 25 m range with it (adapt_to_sensor); the 10 m is for other sensors and a preset named.
[[nodiscard]] Params room_preset();
/// The preset called `name` ("indoor", "room" or "outdoor"); throws hmap::Error for any other name.
[[nodiscard]] Params preset(std::string_view name);

/// The values a parameter may take: an interval, each end closed or open. Every parameter has
/// finite ends, so that nothing sized or looped from a parameter is unbounded.
struct ParamRange {
  double min = 0.0;
  double max = 0.0;
  bool min_open = false;  ///< min itself is excluded: (min, ...
  bool max_open = false;  ///< max itself is excluded: ..., max)

  [[nodiscard]] bool contains(double v) const {
    return (min_open ? v > min : v >= min) && (max_open ? v < max : v <= max);  // false for NaN
  }
  /// "[0.001, 100]", "(0, 0.5)".
  [[nodiscard]] std::string text() const;
};

/// One named parameter: a scalar field of Params, seen as a double.
struct ParamRef {
  std::string name;         ///< "map.cell_size"
  std::string unit;         ///< "m", "-", "cells", ...
  std::string description;  ///< one line
  std::function<double()> get;
  std::function<void(double)> set;  ///< rounds for integer fields
  ParamRange range;         ///< enforced by validate()
};

/// Every scalar parameter of `params` by its dotted name (enums as their integer value).
[[nodiscard]] std::vector<ParamRef> param_refs(Params& params);

/// Throws hmap::Error naming the first parameter that is out of its range (ParamRef::range: the
/// message gives the parameter, its value and the range), or that breaks a rule between
/// parameters (min_range >= max_range, a scan window too large for memory, ...).
void validate(const Params& params);

}  // namespace hmap
