#pragma once
// A map brought to corrected poses (after loop closure) by rebuilding only the tiles the moved
// scans reached. The HMAP is updated per column (merging, III-D, and extrusion, III-E, each change
// only the column they are in), so a tile's columns depend only on the scans that reach it, in
// their order: a tile no moved scan reaches, at its old pose or its new one, is the same in a map
// built at the new poses, and a tile one reaches is built again from every scan that reaches it.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

#include "hmap/maps/cell_centroids.hpp"
#include "hmap/maps/hmap.hpp"

namespace hmap {

/// A square of tiles (HMap::tile_of keys, inclusive).
struct TileSquare {
  CellKey lo;
  CellKey hi;
};

/// A set of tiles kept as sorted, disjoint runs [i_begin, i_end] per tile row j: the squares of
/// a long drive's scans overlap heavily, so this stays small where a bitmap over their bounds
/// (kilometres at fine cells) or a set of single tiles would not.
class TileRuns {
 public:
  void add(const TileSquare& s);
  /// Sorts and unites each row's runs; call after the last add, before the queries.
  void finish();
  [[nodiscard]] bool contains(const CellKey& tile) const { return overlaps(tile.j, tile.i, tile.i); }
  [[nodiscard]] bool overlaps(const TileSquare& s) const;

 private:
  [[nodiscard]] bool overlaps(std::int32_t j, std::int32_t i0, std::int32_t i1) const;
  std::unordered_map<std::int32_t, std::vector<std::pair<std::int32_t, std::int32_t>>> rows_;
};

/// What rebuild_moved_tiles did, with the map it made.
struct TileRebuild {
  TileRebuild(HMap m, PoseList poses) : map(std::move(m)), T_map_sensor(std::move(poses)) {}
  HMap map;
  /// The poses `map` is built at: the corrected one for a moved scan, the built one for a scan
  /// whose correction moved none of its points farther than the tolerance.
  PoseList T_map_sensor;
  std::size_t scans_moved = 0;       ///< scans whose correction exceeds the tolerance
  std::size_t scans_integrated = 0;  ///< scans read and integrated again (they reach a rebuilt tile)
  std::size_t tiles_rebuilt = 0;     ///< tiles built again that hold HVoxels (a moved scan reaches them)
  std::size_t tiles_kept = 0;        ///< tiles of `built` copied as they were
  bool whole = false;                ///< the whole map was rebuilt instead (slam::map_at_corrected_poses)
  /// The tiles built again: every tile a moved scan reaches at its built pose or its corrected
  /// one (none when `whole`: then every tile was).
  TileRuns rebuilt;
  /// The SLAM's cell centroids at T_map_sensor, when slam::map_at_corrected_poses was given the
  /// ones summed at the built poses; else none.
  std::optional<CellCentroids> centroids;
};

/// The tiles a scan taken at `T_map_sensor` can change: every cell its points within map.max_range
/// fall in, and every cell its rays cross, lies in the square of that half-width about the
/// sensor, widened by a cell.
[[nodiscard]] TileSquare scan_tile_square(const MapParams& params, const Pose& T_map_sensor);

/// Told of each scan a rebuild integrates: its index, its points in the sensor frame, the pose.
using RebuiltScan = std::function<void(std::size_t, const PointCloud&, const Pose&)>;

/// The farthest a point within `max_range` of the sensor moves from pose `a` to pose `b` can go,
/// bounded: |t_b − t_a| + angle(R_b R_aᵀ) · max_range [m].
[[nodiscard]] double pose_displacement_bound(const Pose& a, const Pose& b, double max_range);

/// `built`, made by integrating scan k at T_built[k] in order (Mapper::integrate, as
/// slam::rebuild_map does), brought to T_corrected: a scan whose correction moves its points by at
/// most `tolerance` metres (pose_displacement_bound) keeps its built pose; the tiles any other scan
/// reaches at either pose are built again from every scan that reaches them at its new pose, read
/// with scan(k, out) (its points in the sensor frame) and, when given, passed on to
/// integrated(k, points, pose) once integrated. The result holds, column for column, what
/// rebuilding the whole map at result.T_map_sensor would. Throws hmap::Error when the pose lists'
/// sizes differ, a pose is not finite or beyond the map's key range, or the tolerance is negative
/// or not finite.
[[nodiscard]] TileRebuild rebuild_moved_tiles(const HMap& built, std::span<const Pose> T_built,
                                              std::span<const Pose> T_corrected, double tolerance,
                                              const std::function<void(std::size_t, PointCloud&)>& scan,
                                              const RebuiltScan& integrated = {});

}  // namespace hmap
