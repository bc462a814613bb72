#pragma once
// The 2.5D elevation map of the paper's comparison pipeline [9]: one height per grid cell, with
// its variance, as ANYbotics elevation_mapping keeps it. Storage only; the update rules are in
// elevation_mapper.hpp.
//
// Cells live in the same unbounded sparse 8 × 8 tiles as the HMAP, keyed like it
// (key = floor(x / cell)), so both maps index the same cells.

#include <array>
#include <cstdint>
#include <limits>
#include <optional>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"
#include "hmap/maps/tile_index.hpp"

namespace hmap {

/// One cell of the elevation map: 16 bytes.
struct ElevationCell {
  float elevation = std::numeric_limits<float>::quiet_NaN();  ///< [m] estimated surface height
  float variance = std::numeric_limits<float>::quiet_NaN();   ///< [m²] of `elevation`
  float lowest = std::numeric_limits<float>::quiet_NaN();     ///< [m] lowest point ever seen here
  std::uint32_t points = 0;                                   ///< points that fell in the cell

  /// False for a cell never observed (its fields are NaN and 0).
  [[nodiscard]] bool known() const { return points > 0; }
};

/// Size figures of an elevation map.
struct ElevationMapStats {
  std::size_t cells = 0;         ///< observed cells
  std::size_t tiles = 0;
  std::size_t memory_bytes = 0;  ///< tiles and the tile index
  Eigen::AlignedBox3d bounds;    ///< cell extents in x, y, elevations in z; empty when no cell
};

class ElevationMap {
 public:
  static constexpr int kTileBits = 3;
  static constexpr int kTileSize = 1 << kTileBits;  ///< cells per tile edge
  static constexpr int kTileCells = kTileSize * kTileSize;
  /// Cell keys are kept within ±2^30, as the HMAP's.
  static constexpr double kMaxKey = 1073741824.0;

  struct Tile {
    std::array<ElevationCell, kTileCells> cells;
  };

  /// Validates the parameters (throws hmap::Error); the cell size is params.map.cell_size.
  explicit ElevationMap(const Params& params);

  [[nodiscard]] const Params& params() const { return params_; }
  [[nodiscard]] double cell_size() const { return params_.map.cell_size; }

  /// The cell holding (x, y), or nullopt when (x, y) is not finite or beyond ±2^30 cells.
  [[nodiscard]] std::optional<CellKey> key_of(double x, double y) const;
  /// Centre of a cell in map coordinates [m].
  [[nodiscard]] Eigen::Vector2d cell_center(const CellKey& key) const;

  /// The cell `key` if it was ever observed, else nullptr. O(1).
  [[nodiscard]] const ElevationCell* find(const CellKey& key) const;
  [[nodiscard]] const ElevationCell* find(double x, double y) const;
  /// Elevation [m] at (x, y), or nullopt where the map is unknown.
  [[nodiscard]] std::optional<double> elevation_at(double x, double y) const;
  /// The cell `key` for changing it, its tile allocated on first touch.
  [[nodiscard]] ElevationCell& cell_for_update(const CellKey& key);
  /// The tile `tile_key` (see tile_of) for changing many of its cells, allocated on first touch.
  [[nodiscard]] Tile& tile_for_update(const CellKey& tile_key) { return tiles_.find_or_create(tile_key); }

  /// Observed cells (one pass over the tiles).
  [[nodiscard]] std::size_t known_cells() const;
  [[nodiscard]] std::size_t tiles() const { return tiles_.size(); }
  [[nodiscard]] bool empty() const { return tiles_.size() == 0; }
  /// Bytes held: the tiles and the tile index (as HMap::stats().memory_bytes counts them). O(1).
  [[nodiscard]] std::size_t memory_bytes() const;
  [[nodiscard]] ElevationMapStats stats() const;
  void clear() { tiles_.clear(); }

  /// Calls f(CellKey, const ElevationCell&) for every observed cell, in no particular order.
  template <typename F>
  void for_each_cell(F&& f) const {
    tiles_.for_each([&](const CellKey& tile_key, const Tile& tile) {
      for (int local = 0; local < kTileCells; ++local) {
        const ElevationCell& c = tile.cells[local];
        if (c.known()) f(key_in_tile(tile_key, local), c);
      }
    });
  }

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

}  // namespace hmap
