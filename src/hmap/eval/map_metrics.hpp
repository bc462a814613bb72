#pragma once
// Map accuracy against a ground-truth surface: occupied-space precision / recall / F-score on
// voxels of the map's resolution, and the Chamfer distance between the map's recovered points and
// the truth points. Pure: map and points in, numbers out.
//
// Empty inputs are not errors: the counts are 0, a ratio whose denominator is 0 is 0, a mean
// distance with nothing to measure is NaN, and `map_empty` / `truth_empty` say why.

#include <cstddef>
#include <cstdint>

#include "hmap/core/types.hpp"
#include "hmap/maps/hmap.hpp"

namespace hmap {

/// Settings of the map evaluation.
struct MapEvalParams {
  double voxel_height = 0.0;         ///< [m] vertical voxel edge; 0 = the map's cell size
  int tolerance_voxels = 1;          ///< k of the tolerant score: a match may be up to k voxels
                                     ///< away on each axis, a (2k+1)³ neighbourhood [voxels]
  double distance_threshold = 0.0;   ///< [m] of the Chamfer "within" fractions; 0 = the map's cell size
  /// Recovered points per HVoxel for the Chamfer distance [-]. An HVoxel taller than this many
  /// vertical voxels is sampled with this many evenly spaced points instead (both ends kept), so a
  /// corrupt kilometre-tall HVoxel cannot exhaust memory; 4096 is 1 km at 25 cm.
  std::size_t max_points_per_hvoxel = 4096;
};

/// Occupied-space scores at one tolerance. Voxel (i, j, l) is the map cell (i, j) in x, y and
/// [l·h, (l+1)·h) in z for the vertical voxel size h.
struct OccupancyScores {
  int tolerance_voxels = 0;               ///< k: matches up to k voxels away on each axis
  std::uint64_t truth_voxels = 0;         ///< voxels holding at least one truth point
  std::uint64_t truth_voxels_recalled = 0;  ///< of those, with a map voxel within k
  std::uint64_t map_voxels = 0;           ///< voxels an HVoxel's [z_min, z_max] overlaps
  std::uint64_t map_voxels_matched = 0;   ///< of those, with a truth voxel within k
  double precision = 0.0;                 ///< map_voxels_matched / map_voxels; 0 if no map voxel
  double recall = 0.0;                    ///< truth_voxels_recalled / truth_voxels; 0 if no truth voxel
  double f_score = 0.0;                   ///< 2PR / (P + R); 0 if P + R = 0
};

/// Nearest-neighbour distances between two point sets.
struct ChamferScores {
  std::size_t map_points = 0;
  std::size_t truth_points = 0;
  double accuracy_m = 0.0;          ///< mean over map points of the distance to the nearest truth point; NaN if either set is empty
  double completeness_m = 0.0;      ///< mean over truth points of the distance to the nearest map point; NaN if either set is empty
  double chamfer_m = 0.0;           ///< (accuracy_m + completeness_m) / 2
  double threshold_m = 0.0;         ///< distance of the two fractions below
  double accuracy_within = 0.0;     ///< fraction of map points with a truth point within threshold_m; 0 if either set is empty
  double completeness_within = 0.0; ///< fraction of truth points with a map point within threshold_m; 0 if either set is empty
};

/// Every number of one map evaluation.
struct MapMetrics {
  double cell_size_m = 0.0;         ///< voxel edge in x and y: the map's cell size
  double voxel_height_m = 0.0;      ///< voxel edge in z actually used
  bool map_empty = false;           ///< the map has no HVoxel: precision and map-side distances are undefined
  bool truth_empty = false;         ///< no truth point: recall and truth-side distances are undefined
  OccupancyScores exact;            ///< tolerance 0: the same voxel
  OccupancyScores tolerant;         ///< tolerance MapEvalParams::tolerance_voxels
  ChamferScores chamfer;            ///< map points: recovered every voxel_height_m (recover_points)
  std::size_t hvoxels_capped = 0;   ///< HVoxels sampled with max_points_per_hvoxel points only
};

/// Evaluates `map` against the true surface `points_truth` (in the map frame). Throws hmap::Error
/// for bad parameters, a non-finite truth point or HVoxel, or a truth point beyond the map's keys.
[[nodiscard]] MapMetrics evaluate_map(const HMap& map, const PointCloud& points_truth,
                                      const MapEvalParams& params = {});

/// Occupied-space scores at one tolerance (the voxel counting of evaluate_map). Huge HVoxels cost
/// O(1): each column's occupied voxels are counted as integer z-index ranges, never enumerated.
[[nodiscard]] OccupancyScores occupancy_scores(const HMap& map, const PointCloud& points_truth,
                                               double voxel_height, int tolerance_voxels);

/// Chamfer distances between two clouds by kd-tree nearest neighbours (nanoflann), queries in
/// parallel. Throws hmap::Error for a non-finite point or a threshold that is negative.
[[nodiscard]] ChamferScores chamfer_scores(const PointCloud& points_map, const PointCloud& points_truth,
                                           double threshold_m);

/// The map's occupied space as points, and how many HVoxels were capped.
struct RecoveredPoints {
  PointCloud points_map;
  std::size_t capped_hvoxels = 0;  ///< HVoxels that got max_points_per_hvoxel points only
};

/// The points of recover_points(map, z_step), except that an HVoxel needing more than
/// `max_points_per_hvoxel` (>= 2) points gets that many, evenly spaced from z_min to z_max.
[[nodiscard]] RecoveredPoints recover_points_capped(const HMap& map, double z_step,
                                                    std::size_t max_points_per_hvoxel);

}  // namespace hmap
