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

template <typename KeyOf>
void Mapper::group_by_tile(const ScanWindow& window, std::size_t n, KeyOf key_of, TileGroups& groups) {
  groups.tile_lo = HMap::tile_of({window.center.i - window.half, window.center.j - window.half});
  const CellKey tile_hi = HMap::tile_of({window.center.i + window.half, window.center.j + window.half});
  groups.tiles_wide = static_cast<std::size_t>(tile_hi.j - groups.tile_lo.j + 1);
  const auto tiles_high = static_cast<std::size_t>(tile_hi.i - groups.tile_lo.i + 1);
  groups.start.assign(groups.tiles_wide * tiles_high + 1, 0);
  groups.bucket.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const CellKey t = HMap::tile_of(key_of(k));
    const auto b = static_cast<std::uint32_t>(static_cast<std::size_t>(t.i - groups.tile_lo.i) * groups.tiles_wide +
                                              static_cast<std::size_t>(t.j - groups.tile_lo.j));
    groups.bucket[k] = b;
    ++groups.start[b + 1];
  }
  groups.used.clear();
  for (std::size_t b = 0; b + 1 < groups.start.size(); ++b) {
    if (groups.start[b + 1] != 0) groups.used.push_back(static_cast<std::uint32_t>(b));
    groups.start[b + 1] += groups.start[b];
  }
  // start[b] as the write cursor of tile b, then restored from the tile before.
  groups.order.resize(n);
  for (std::size_t k = 0; k < n; ++k) groups.order[groups.start[groups.bucket[k]]++] = static_cast<std::uint32_t>(k);
  for (std::size_t b = groups.start.size() - 1; b > 0; --b) groups.start[b] = groups.start[b - 1];
  groups.start[0] = 0;
}

void Mapper::merge_scan() {
  const MapParams& p = map_.params().map;
  // Tile by tile: one lookup per tile, and its buffer in cache while its columns merge. The tiles
  // the map lacks are made first, in the order of their first cell in the scan, as a lookup per
  // cell made them: the map's tiles stay in the same order.
  TileGroups& g = merge_groups_;
  group_by_tile(scan_.window, scan_.cells.size(), [this](std::size_t k) { return scan_.cells[k].key; }, g);
  tile_of_group_.resize(g.used.size());
  new_tiles_.clear();
  for (std::size_t u = 0; u < g.used.size(); ++u) {
    tile_of_group_[u] = map_.find_tile(g.tile_key(g.used[u]));
    if (tile_of_group_[u] == nullptr) new_tiles_.emplace_back(g.order[g.start[g.used[u]]], static_cast<std::uint32_t>(u));
  }
  std::sort(new_tiles_.begin(), new_tiles_.end());
  for (const auto& [first, u] : new_tiles_) tile_of_group_[u] = &map_.tile_for_update(g.tile_key(g.used[u]));
  for (std::size_t u = 0; u < g.used.size(); ++u) {
    HMap::Tile& tile = *tile_of_group_[u];
    const std::uint32_t b = g.used[u];
    for (std::uint32_t k = g.start[b]; k != g.start[b + 1]; ++k) {
      const ScanCell& cell = scan_.cells[g.order[k]];
      TileColumn column(tile, HMap::local_index(cell.key));
      // III-D joins within the gap the cell's points were clustered with (map.ring_gap_slope).
      const float cell_gap = hvoxelizer_.cell_gap(scan_, g.order[k]);
      for (const HVoxel& v : scan_.hvoxels_of(cell)) column.merge(v, cell_gap, p);
    }
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
  // share its buffer, so each tile's cells go to one thread. The cells are grouped by tile, so
  // that a tile is looked up once for all its cells and its buffer stays in cache while they are
  // carved; within a tile they keep the tracer's order, so the edits, and the buffer's growth,
  // are the same whatever the threads.
  TileGroups& g = free_groups_;
  const ScanWindow& window = scan_.window;
  group_by_tile(window, free_cells.size(), [&free_cells](std::size_t k) { return free_cells[k]->key; }, g);
  tbb::enumerable_thread_specific<std::vector<FreeHVoxel>> pieces_of_thread;
  tbb::enumerable_thread_specific<ExtrusionCounts> counts_of_thread;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, g.used.size(), 16), [&](const auto& range) {
    auto& pieces = pieces_of_thread.local();
    auto& counts = counts_of_thread.local();
    for (std::size_t u = range.begin(); u != range.end(); ++u) {
      const std::uint32_t b = g.used[u];
      HMap::Tile* tile = map_.find_tile(g.tile_key(b));
      if (tile == nullptr) continue;
      for (std::uint32_t k = g.start[b]; k != g.start[b + 1]; ++k) {
        const FreeCell& free_cell = *free_cells[g.order[k]];
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
