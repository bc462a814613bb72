#pragma once
// The HMAP mapping pipeline of section III: a scan and its pose in, the map updated.

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "hmap/maps/extrusion.hpp"
#include "hmap/maps/free_space.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/maps/scan_hvoxels.hpp"

namespace hmap {

/// What one call of Mapper::integrate did.
struct ScanStats {
  std::size_t points_in = 0;
  std::size_t points_kept = 0;
  std::size_t dropped_non_finite = 0;
  std::size_t dropped_range = 0;
  std::size_t scan_cells = 0;     ///< cells of R holding points
  std::size_t scan_hvoxels = 0;   ///< HVoxels of R
  std::size_t rays = 0;           ///< HVoxels with ρ >= n_th that cast a ray
  std::size_t free_cells = 0;     ///< cells given free HVoxels
  ExtrusionCounts extrusion;
};

class Mapper {
 public:
  /// A new, empty map. Throws hmap::Error for invalid parameters.
  explicit Mapper(const Params& params);
  /// Continues an existing map (for instance one loaded from a file), with its parameters.
  explicit Mapper(HMap map);

  /// Integrates one scan taken at T_map_sensor: its HVoxel representation (Alg. 1, 2), free
  /// space by ray tracing (Alg. 3), merging into the map (III-D) and extrusion (III-E).
  ScanStats integrate(std::span<const Point3f> points_sensor, const Pose& T_map_sensor);

  [[nodiscard]] const HMap& map() const { return map_; }
  [[nodiscard]] HMap& map() { return map_; }
  /// The HVoxel representation R of the last integrated scan.
  [[nodiscard]] const ScanHVoxels& last_scan() const { return scan_; }
  [[nodiscard]] const FreeSpaceTracer& free_space() const { return tracer_; }

 private:
  void merge_scan();                   // III-D
  void extrude_free_space(ScanStats& stats);  // III-E

  HMap map_;
  ScanHVoxelizer hvoxelizer_;
  FreeSpaceTracer tracer_;
  ScanHVoxels scan_;
  /// Items (scan cells, free cells) grouped by the tile of the scan window their cell falls in: a
  /// stable counting sort, so that each tile is looked up once and its items stay in their order.
  struct TileGroups {
    CellKey tile_lo;                          // the window's first tile
    std::size_t tiles_wide = 0;               // window tiles per row
    std::vector<std::uint32_t> start;         // per window tile: where its items start in `order`
    std::vector<std::uint32_t> bucket;        // per item: its window tile
    std::vector<std::uint32_t> order;         // the items' indices, tile by tile
    std::vector<std::uint32_t> used;          // the window tiles holding items, in window order
    [[nodiscard]] CellKey tile_key(std::uint32_t b) const {
      return {tile_lo.i + static_cast<std::int32_t>(b / tiles_wide), tile_lo.j + static_cast<std::int32_t>(b % tiles_wide)};
    }
  };
  /// Fills `groups` with the indices 0..n-1 by the window tile of key_of(k).
  template <typename KeyOf>
  static void group_by_tile(const ScanWindow& window, std::size_t n, KeyOf key_of, TileGroups& groups);

  TileGroups merge_groups_;                 // the scan's cells (merging)
  TileGroups free_groups_;                  // the free cells (extrusion)
  std::vector<HMap::Tile*> tile_of_group_;  // merging: the tile of each used window tile
  std::vector<std::pair<std::uint32_t, std::uint32_t>> new_tiles_;  // merging: (first cell, used index)
};

}  // namespace hmap
