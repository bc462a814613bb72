#include "hmap/maps/mapper.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace hmap {

Mapper::Mapper(const Params& params) : Mapper(HMap(params)) {}

Mapper::Mapper(HMap map)
    : map_(std::move(map)),
      hvoxelizer_(map_.params().map),
      tracer_(map_.params().map) {}

ScanStats Mapper::integrate(std::span<const Point3f> points_sensor, const Pose& T_map_sensor) {
  // Alg. 1 and Alg. 2: the HVoxel representation R of the scan, in the map frame.
  hvoxelizer_.build(points_sensor, T_map_sensor, scan_);
  ScanStats stats;
  stats.points_in = scan_.points_in;
  stats.points_kept = scan_.points_kept;
  stats.dropped_non_finite = scan_.dropped_non_finite;
  stats.dropped_range = scan_.dropped_range;
  stats.scan_cells = scan_.cells.size();
  stats.scan_hvoxels = scan_.hvoxels.size();

  const bool carve = map_.params().map.free_space == FreeSpaceMode::kRayTracing;
  if (carve) {
    // Alg. 3 (free-space HVoxels by HVoxel ray tracing) reads only R; III-D (merging R into the
    // map) writes only the map: they run side by side.
    tracer_.trace(scan_, [&] { merge_scan(); });
  } else {
    merge_scan();  // III-D
  }
  // III-E: extrusion of the merged map by the free-space HVoxels.
  if (carve) {
    stats.rays = tracer_.rays();
    stats.free_cells = tracer_.cells().size();
    extrude_free_space(stats);
  }
  return stats;
}

void Mapper::merge_scan() {
  const MapParams& p = map_.params().map;
  const auto gap = static_cast<float>(p.point_distance_threshold);
  for (const ScanCell& cell : scan_.cells) {
    TileColumn column = map_.column_for_update(cell.key);
    for (const HVoxel& v : scan_.hvoxels_of(cell)) column.merge(v, gap, p);
  }
}

namespace {

/// Appends to `out` the parts of `f` outside every interval of `occupied` (sorted, disjoint).
void subtract(const FreeHVoxel& f, std::span<const HVoxel> occupied, std::vector<FreeHVoxel>& out) {
  float lo = f.z_min;
  for (const HVoxel& v : occupied) {
    if (v.z_max < lo) continue;
    if (v.z_min > f.z_max) break;
    if (v.z_min > lo) out.push_back({lo, v.z_min, f.rays});
    lo = std::max(lo, v.z_max);
    if (lo >= f.z_max) return;
  }
  if (lo < f.z_max) out.push_back({lo, f.z_max, f.rays});
}

}  // namespace

void Mapper::extrude_free_space(ScanStats& stats) {
  const MapParams& p = map_.params().map;
  const auto& scan_cell_of_window = hvoxelizer_.cell_of_window();
  const auto& free_cells = tracer_.cells();
  // Each free cell changes only its own column, and no tile is created; the columns of a tile
  // share its buffer, so each tile's cells go to one thread. The cells are grouped by tile (a
  // stable counting sort over the window's tiles), so that a tile is looked up once for all its
  // cells and its buffer stays in cache while they are carved; within a tile they keep the
  // tracer's order, so the edits, and the buffer's growth, are the same whatever the threads.
  const ScanWindow& window = scan_.window;
  const CellKey tile_lo = HMap::tile_of({window.center.i - window.half, window.center.j - window.half});
  const CellKey tile_hi = HMap::tile_of({window.center.i + window.half, window.center.j + window.half});
  const auto tiles_wide = static_cast<std::size_t>(tile_hi.j - tile_lo.j + 1);
  const auto tiles_high = static_cast<std::size_t>(tile_hi.i - tile_lo.i + 1);
  tile_start_.assign(tiles_wide * tiles_high + 1, 0);
  bucket_of_cell_.resize(free_cells.size());
  for (std::size_t k = 0; k < free_cells.size(); ++k) {
    const CellKey t = HMap::tile_of(free_cells[k]->key);
    const auto bucket = static_cast<std::uint32_t>(static_cast<std::size_t>(t.i - tile_lo.i) * tiles_wide +
                                                   static_cast<std::size_t>(t.j - tile_lo.j));
    bucket_of_cell_[k] = bucket;
    ++tile_start_[bucket + 1];
  }
  tiles_used_.clear();
  for (std::size_t b = 0; b + 1 < tile_start_.size(); ++b) {
    if (tile_start_[b + 1] != 0) tiles_used_.push_back(static_cast<std::uint32_t>(b));
    tile_start_[b + 1] += tile_start_[b];
  }
  by_tile_.resize(free_cells.size());
  {
    // tile_start_[b] as the write cursor of tile b, then restored from the next tile's start.
    for (std::size_t k = 0; k < free_cells.size(); ++k) by_tile_[tile_start_[bucket_of_cell_[k]]++] = free_cells[k];
    for (std::size_t b = tile_start_.size() - 1; b > 0; --b) tile_start_[b] = tile_start_[b - 1];
    tile_start_[0] = 0;
  }
  tbb::enumerable_thread_specific<std::vector<FreeHVoxel>> pieces_of_thread;
  tbb::enumerable_thread_specific<ExtrusionCounts> counts_of_thread;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tiles_used_.size(), 16), [&](const auto& range) {
    auto& pieces = pieces_of_thread.local();
    auto& counts = counts_of_thread.local();
    for (std::size_t u = range.begin(); u != range.end(); ++u) {
      const std::uint32_t bucket = tiles_used_[u];
      const CellKey tile_key{tile_lo.i + static_cast<std::int32_t>(bucket / tiles_wide),
                             tile_lo.j + static_cast<std::int32_t>(bucket % tiles_wide)};
      HMap::Tile* tile = map_.find_tile(tile_key);
      if (tile == nullptr) continue;
      for (std::uint32_t k = tile_start_[bucket]; k != tile_start_[bucket + 1]; ++k) {
        const FreeCell& free_cell = *by_tile_[k];
        TileColumn column(*tile, HMap::local_index(free_cell.key));
        if (column.empty()) continue;
        // Within one scan a hit outranks a pass-through, as in OctoMap: the scan's own HVoxels in
        // this cell are not carved by its own rays.
        const std::uint32_t own = scan_cell_of_window[window.index(free_cell.key)];
        std::array<FreeHVoxel, FreeCell::kMaxIntervals> lanes;
        std::span<const FreeHVoxel> free = free_cell.hvoxels(lanes);
        if (own != 0) {
          pieces.clear();
          const auto own_hvoxels = scan_.hvoxels_of(scan_.cells[own - 1]);
          for (const FreeHVoxel& f : free) subtract(f, own_hvoxels, pieces);
          free = pieces;
        }
        extrude(column, free, p, counts);
      }
    }
  });
  for (const ExtrusionCounts& c : counts_of_thread) {
    stats.extrusion.updated += c.updated;
    stats.extrusion.trimmed += c.trimmed;
    stats.extrusion.subdivided += c.subdivided;
    stats.extrusion.removed += c.removed;
  }
}

}  // namespace hmap
