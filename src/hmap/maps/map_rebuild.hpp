#pragma once
// A map brought to corrected poses (after loop closure) by rebuilding only the tiles the moved
// scans reached. The HMAP is updated per column (merging, III-D, and extrusion, III-E, each change
// only the column they are in), so a tile's columns depend only on the scans that reach it, in
// their order: a tile no moved scan reaches, at its old pose or its new one, is the same in a map
// built at the new poses, and a tile one reaches is built again from every scan that reaches it.

#include <cstddef>
#include <functional>
#include <span>

#include "hmap/maps/hmap.hpp"

namespace hmap {

/// What rebuild_moved_tiles did, with the map it made.
struct TileRebuild {
  HMap map;
  /// The poses `map` is built at: the corrected one for a moved scan, the built one for a scan
  /// whose correction moved none of its points farther than the tolerance.
  PoseList T_map_sensor;
  std::size_t scans_moved = 0;       ///< scans whose correction exceeds the tolerance
  std::size_t scans_integrated = 0;  ///< scans read and integrated again (they reach a rebuilt tile)
  std::size_t tiles_rebuilt = 0;     ///< tiles built again that hold HVoxels (a moved scan reaches them)
  std::size_t tiles_kept = 0;        ///< tiles of `built` copied as they were
  bool whole = false;                ///< the whole map was rebuilt instead (slam::map_at_corrected_poses)
};

/// The farthest a point within `max_range` of the sensor moves from pose `a` to pose `b` can go,
/// bounded: |t_b − t_a| + angle(R_b R_aᵀ) · max_range [m].
[[nodiscard]] double pose_displacement_bound(const Pose& a, const Pose& b, double max_range);

/// The tiles (HMap::tile_of keys, inclusive) a scan taken at `T_map_sensor` can change: every cell
/// its points within map.max_range fall in, and every cell its rays cross, lies in the square of
/// that half-width about the sensor, widened by a cell.
struct TileSquare {
  CellKey lo;
  CellKey hi;
};
[[nodiscard]] TileSquare scan_tile_square(const MapParams& params, const Pose& T_map_sensor);

/// `built`, made by integrating scan k at T_built[k] in order (Mapper::integrate, as
/// slam::rebuild_map does), brought to T_corrected: a scan whose correction moves its points by at
/// most `tolerance` metres (pose_displacement_bound) keeps its built pose; the tiles any other scan
/// reaches at either pose are built again from every scan that reaches them at its new pose, read
/// with scan(k, out) (its points in the sensor frame). The result holds, column for column, what
/// rebuilding the whole map at result.T_map_sensor would. Throws hmap::Error when the pose lists'
/// sizes differ, a pose is not finite or beyond the map's key range, or the tolerance is negative
/// or not finite.
[[nodiscard]] TileRebuild rebuild_moved_tiles(const HMap& built, std::span<const Pose> T_built,
                                              std::span<const Pose> T_corrected, double tolerance,
                                              const std::function<void(std::size_t, PointCloud&)>& scan);

}  // namespace hmap
