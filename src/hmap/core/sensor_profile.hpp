#pragma once
// What a scan tells about its sensor, and the defaults chosen from it: a spinning LiDAR's ring
// spacing sets how the height gap grows with range, so that a far wall stays one HVoxel (map.ring_gap_slope).

#include <span>
#include <string>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"

namespace hmap {

/// The sensor as one scan shows it.
struct SensorProfile {
  std::size_t points = 0;           ///< finite points looked at (at most 200,000, evenly thinned)
  int rings = 0;                    ///< distinct elevation rings found (0: not ring-structured, e.g. RGB-D)
  double ring_spacing = 0.0;        ///< [rad] median elevation step between neighbouring rings; 0 if no rings
  double range_p95 = 0.0;           ///< [m] 95th percentile of the points' range
  double azimuth_coverage = 0.0;    ///< [-] share of the 360 one-degree azimuth bins that hold a point
};

/// A spinning LiDAR: rings, and points all around (more than half of the azimuths). The rings alone
/// are not enough: the simulated Kinect's 70° view showed 4 "rings" (its rows beyond 5 m).
[[nodiscard]] inline bool is_spinning_lidar(const SensorProfile& s) { return s.rings > 0 && s.azimuth_coverage > 0.5; }

/// Elevations atan2(z, √(x²+y²)) of the points farther than 5 m (nearer, the beams' offset from
/// the sensor origin blurs the rings; of those from 2 m on when fewer than 1000 lie beyond 5 m
/// and the points cover more than half of the azimuths: a LiDAR in a small closed room), in
/// 0.05° bins; runs of bins holding at least 0.1 % of the
/// points are rings. Ring-structured when at least 4 rings fill under half of the elevation span
/// they cover (a depth camera's or sweeping laser's elevations fill it) and are at least 0.2° apart.
/// The azimuth coverage counts every finite point off the vertical axis.
[[nodiscard]] SensorProfile profile_scan(std::span<const Point3f> points_sensor);

/// The preset that fits the sensor, when the user named none: "indoor" when 95 % of the scan's
/// points lie within the indoor preset's range limit (map.max_range, 5 m: a depth camera, a laser in
/// a small room), "room" when within the room preset's (10 m: a LiDAR inside a building), so that a
/// coarser preset's reach and cells would see nothing more and lose the detail; else "outdoor". A
/// scan of fewer than 1000 points (no real sensor's) gets "outdoor". `reason` (optional) says why,
/// for the summary.
[[nodiscard]] std::string preset_for_sensor(const SensorProfile& sensor, std::string* reason = nullptr);

/// One default chosen from the data, for the summary.
struct ChosenDefault {
  std::string name;
  double value = 0.0;
  std::string reason;
};

/// Adapts `p` to the sensor, for parameters still at their value in `preset_params` (a value the
/// user set, even to the preset's, is the user's when it differs; equal values are taken as unset,
/// but for map.max_range when `max_range_named`, and for the height gap (map.ring_gap_slope and
/// map.point_distance_threshold) when `gap_named`: resolve_params_for_scan says so for a range, a
/// preset or a gap the user named). Returns what it changed.
/// - map.max_range, for a LiDAR (is_spinning_lidar) whose preset reaches less: the LiDAR's own
///   reach, where its rings lie map.ring_gap_max apart on a wall (ring_gap_max / (1.1 × tan(spacing)),
///   whole metres: a VLP-16's 2° rings 78 m), at least the outdoor preset's 25 m, at most the 100 m
///   the common spinning LiDARs reach and 512 cells each way of the scan window (never under 25 m or
///   2048 cells: validate()'s limit). The first scan tells the size
///   of the place the recording starts in, not the sensor's reach: a LiDAR that starts in a room sees
///   the hall or street beyond it later, and where nothing stands near, its far walls hold the match.
/// - map.ring_gap_slope = 1.1 × tan(ring spacing) for a LiDAR, when neither it nor
///   map.point_distance_threshold was set (`--set map.ring_gap_slope=0` keeps one gap): two neighbouring rings on a wall at a distance d are
///   d · tan(spacing) apart, so the height gap of each cell grows with its distance from the
///   sensor (from the preset's 0.4 m, at most map.ring_gap_max), and a far wall stays one HVoxel instead of one
///   per ring (a VLP-16's 2° rings past 10.4 m) while a near table stays apart from the floor.
/// - map.point_distance_threshold = ring spacing × map.max_range as it was before the first line
///   (clamped to [preset, 1 m]) for rows that read as rings but not all around (no LiDAR).
[[nodiscard]] std::vector<ChosenDefault> adapt_to_sensor(Params& p, const Params& preset_params,
                                                         const SensorProfile& sensor, bool max_range_named = false,
                                                         bool gap_named = false);

}  // namespace hmap
