#pragma once
// Maps of different sessions made one: one map's HVoxels merged into another's column by column
// (III-D, as a scan's are), and a map moved rigidly in the plane before it is merged. A map cut to
// a range of tiles, so that one built in parts (each its own tiles) is put together by merging.

#include <cstddef>

#include <Eigen/Geometry>
#include <cstdint>

#include "hmap/maps/hmap.hpp"

namespace hmap {

/// A rigid motion of a whole map that keeps gravity: a turn by `yaw` about z, then a shift.
struct PlanarShift {
  double x = 0.0;    ///< [m]
  double y = 0.0;    ///< [m]
  double z = 0.0;    ///< [m]
  double yaw = 0.0;  ///< [rad]
};

/// Tiles [i_begin, i_end) × [j_begin, j_end), in tile keys (HMap::tile_of: cell key >> kTileBits).
struct TileRange {
  std::int32_t i_begin = 0;
  std::int32_t j_begin = 0;
  std::int32_t i_end = 0;
  std::int32_t j_end = 0;

  [[nodiscard]] bool contains(const CellKey& tile_key) const {
    return tile_key.i >= i_begin && tile_key.i < i_end && tile_key.j >= j_begin && tile_key.j < j_end;
  }
};

/// The axis-aligned bounds [m] of the square [x0, x0 + edge] × [y0, y0 + edge] turned by
/// shift.yaw and moved by (shift.x, shift.y): where a tile of a map or grid lands under `shift`.
[[nodiscard]] Eigen::AlignedBox2d moved_square_bounds(double x0, double y0, double edge, const PlanarShift& shift);

/// Copies the non-empty columns of `tile` (tile key `tile_key` of another map with the same cell)
/// into `into`'s same cells, after what they hold.
void copy_tile(HMap& into, const CellKey& tile_key, const HMap::Tile& tile);

/// What merge_map did.
struct MapMergeStats {
  std::size_t columns_added = 0;   ///< columns of `from` where `into` had none: copied as they are
  std::size_t columns_merged = 0;  ///< columns both maps hold: united by III-D
  std::size_t hvoxels_before = 0;  ///< of `into`
  std::size_t hvoxels_from = 0;    ///< of `from`
  std::size_t hvoxels_after = 0;   ///< of `into` after the merge
};

/// Merges every HVoxel of `from` into `into`'s column of the same cell: a column `into` does not
/// hold is copied exactly; in one both hold, each HVoxel is united with those within `into`'s
/// map.point_distance_threshold (III-D: extents joined, counts added, density of eq. 1 anew).
/// What `from`'s free space would have carved out of `into` is not carved: the free space of its
/// scans is not kept in a map. Throws hmap::Error when the cell sizes differ, or when the result
/// would pass `budget` (checked per tile of `from`).
MapMergeStats merge_map(HMap& into, const HMap& from, const MemoryBudget& budget = {});

/// `map` moved by `shift`: each cell of the result takes the column of `map` under its centre
/// moved back (nearest cell; the picture-rotation rule, so no cell is left empty between two
/// filled ones and none is filled twice), its HVoxels raised by shift.z. A shift by whole cells
/// without a turn moves every column exactly. Throws hmap::Error for a shift that is not finite,
/// that would move cells beyond the key range, or a result beyond `budget`.
[[nodiscard]] HMap shifted_map(const HMap& map, const PlanarShift& shift, const MemoryBudget& budget = {});

/// The columns of `map` in the tiles of `range`, copied exactly, with its parameters; the rest
/// left out. A column is changed only by the scans whose points or rays reach its cell, so the
/// map of every scan that reaches a range, cut to it, equals the whole run's map there, and maps
/// cut to disjoint ranges merge (merge_map) without touching each other's columns. Throws
/// hmap::Error for a range with begin > end.
[[nodiscard]] HMap crop_map(const HMap& map, const TileRange& range);

}  // namespace hmap
