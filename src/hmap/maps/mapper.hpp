#pragma once
// The HMAP mapping pipeline of section III: a scan and its pose in, the map updated.

#include <cstdint>
#include <span>
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
  // The free cells grouped by the tile of the scan window they fall in (extrusion): a counting sort.
  std::vector<std::uint32_t> tile_start_;      // per window tile: where its cells start in by_tile_
  std::vector<std::uint32_t> bucket_of_cell_;  // per free cell: its window tile
  std::vector<const FreeCell*> by_tile_;       // the free cells, tile by tile, in tracer order within one
  std::vector<std::uint32_t> tiles_used_;      // the window tiles holding free cells
};

}  // namespace hmap
