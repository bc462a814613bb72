#pragma once
// The HMAP: an unbounded sparse 2D grid of columns of HVoxels (section III).
//
// Cells live in square tiles of kTileSize × kTileSize allocated on first touch and found by a
// hash of the tile key, so the map grows with the area seen and needs no bounding box.

#include <array>
#include <memory>
#include <optional>

#include "hmap/core/budget.hpp"
#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"
#include "hmap/maps/column.hpp"
#include "hmap/maps/tile_index.hpp"

namespace hmap {

/// Size figures of a map.
struct MapStats {
  std::size_t cells = 0;         ///< columns holding at least one HVoxel
  std::size_t hvoxels = 0;
  std::size_t tiles = 0;
  std::size_t memory_bytes = 0;  ///< tiles, heap HVoxels and the tile index
  Eigen::AlignedBox3d bounds;    ///< of the HVoxels (cell extents in x, y); empty when no HVoxel
};

class HMap {
 public:
  static constexpr int kTileBits = 3;
  static constexpr int kTileSize = 1 << kTileBits;  ///< cells per tile edge
  static constexpr int kTileCells = kTileSize * kTileSize;
  /// Cell keys are kept within ±2^30 so neighbours and tile keys never overflow.
  static constexpr double kMaxKey = 1073741824.0;

  /// The columns of kTileSize × kTileSize cells, packed (column.hpp); cell `local_index(key)`.
  using Tile = ColumnTile;
  static_assert(ColumnTile::kCells == kTileCells);

  /// Validates the parameters (throws hmap::Error).
  explicit HMap(const Params& params);

  [[nodiscard]] const Params& params() const { return params_; }
  [[nodiscard]] double cell_size() const { return params_.map.cell_size; }

  /// The cell holding (x, y), or nullopt when (x, y) is not finite or beyond ±2^30 cells.
  [[nodiscard]] std::optional<CellKey> key_of(double x, double y) const;
  /// Centre of a cell in map coordinates [m].
  [[nodiscard]] Eigen::Vector2d cell_center(const CellKey& key) const;

  /// The column of a cell (empty if nothing was ever stored there). O(1); valid until the map
  /// changes.
  [[nodiscard]] ColumnView column(const CellKey& key) const;
  [[nodiscard]] ColumnView column(double x, double y) const;
  /// The column of a cell for changing it, or nullopt if its tile was never allocated.
  /// Columns of one tile share its buffer: threads may change columns of different tiles only.
  [[nodiscard]] std::optional<TileColumn> find_column(const CellKey& key) {
    Tile* tile = tiles_.find(tile_of(key));
    if (tile == nullptr) return std::nullopt;
    return TileColumn(*tile, local_index(key));
  }
  /// The column of a cell, its tile allocated on first touch.
  [[nodiscard]] TileColumn column_for_update(const CellKey& key);
  /// A tile for changing its columns, or nullptr. `tile_key` as in tile_of().
  [[nodiscard]] Tile* find_tile(const CellKey& tile_key) { return tiles_.find(tile_key); }
  /// A tile for changing its columns, allocated if absent. `tile_key` as in tile_of().
  [[nodiscard]] Tile& tile_for_update(const CellKey& tile_key) { return tiles_.find_or_create(tile_key); }
  [[nodiscard]] const Tile* find_tile(const CellKey& tile_key) const { return tiles_.find(tile_key); }
  /// The HVoxel containing (x, y, z), or nullptr. O(1) + O(log n).
  [[nodiscard]] const HVoxel* hvoxel_at(double x, double y, double z) const;
  [[nodiscard]] bool occupied(double x, double y, double z) const {
    return hvoxel_at(x, y, z) != nullptr;
  }

  [[nodiscard]] MapStats stats() const;
  /// stats().memory_bytes without walking the columns: O(tiles), cheap enough to check the map
  /// against a memory budget after every scan.
  [[nodiscard]] std::size_t memory_bytes() const;
  [[nodiscard]] bool empty() const;
  void clear() { tiles_.clear(); }

  /// Calls f(CellKey, ColumnView) for every non-empty column, in no particular order.
  template <typename F>
  void for_each_column(F&& f) const {
    tiles_.for_each([&](const CellKey& tile_key, const Tile& tile) {
      for (int local = 0; local < kTileCells; ++local) {
        const ColumnView c = tile.column(local);
        if (!c.empty()) f(key_in_tile(tile_key, local), c);
      }
    });
  }
  /// Calls f(tile_key, const Tile&) for every allocated tile; tile (a, b) holds cells
  /// [a·kTileSize, (a+1)·kTileSize) × [b·kTileSize, (b+1)·kTileSize).
  template <typename F>
  void for_each_tile(F&& f) const {
    tiles_.for_each(f);
  }
  /// Removes tiles whose columns are all empty, and trims the others' buffers to fit.
  void prune_empty_tiles();

  [[nodiscard]] static CellKey tile_of(const CellKey& key) {
    return {key.i >> kTileBits, key.j >> kTileBits};  // arithmetic shift: floor division
  }
  [[nodiscard]] static int local_index(const CellKey& key) {
    return ((key.i & (kTileSize - 1)) << kTileBits) | (key.j & (kTileSize - 1));
  }
  [[nodiscard]] static CellKey key_in_tile(const CellKey& tile, int local) {
    return {tile.i * kTileSize + (local >> kTileBits), tile.j * kTileSize + (local & (kTileSize - 1))};
  }

 private:
  Params params_;
  TileIndex<Tile> tiles_;
};

/// The occupied space as points: each HVoxel sampled at its cell centre from z_min to z_max
/// every `z_step` metres (both ends included): the paper's height-upsampled point cloud.
/// The points are counted first: more than `budget` holds throws hmap::Error before any is made
/// (a 1.4 kB map whose HVoxels span 100 km asked for gigabytes).
[[nodiscard]] PointCloud recover_points(const HMap& map, double z_step, const MemoryBudget& budget = {});

}  // namespace hmap
