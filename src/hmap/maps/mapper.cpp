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
  // share its buffer, so the cells are dealt into stripes by tile and the stripes run in parallel.
  for (auto& stripe : stripes_) stripe.clear();
  for (const FreeCell* fc : free_cells) {
    const CellKey t = HMap::tile_of(fc->key);
    const auto h = static_cast<std::uint32_t>(t.i) * 0x9E3779B1U ^ static_cast<std::uint32_t>(t.j) * 0x85EBCA77U;
    stripes_[(h >> 16) % stripes_.size()].push_back(fc);
  }
  tbb::enumerable_thread_specific<std::vector<FreeHVoxel>> pieces_of_thread;
  tbb::enumerable_thread_specific<ExtrusionCounts> counts_of_thread;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, stripes_.size(), 1), [&](const auto& range) {
    auto& pieces = pieces_of_thread.local();
    auto& counts = counts_of_thread.local();
    for (std::size_t s = range.begin(); s != range.end(); ++s) {
    for (const FreeCell* fc : stripes_[s]) {
      const FreeCell& free_cell = *fc;
      std::optional<TileColumn> column = map_.find_column(free_cell.key);
      if (!column || column->empty()) continue;
      // Within one scan a hit outranks a pass-through, as in OctoMap: the scan's own HVoxels in
      // this cell are not carved by its own rays.
      const std::uint32_t own = scan_cell_of_window[scan_.window.index(free_cell.key)];
      std::array<FreeHVoxel, FreeCell::kMaxIntervals> lanes;
      std::span<const FreeHVoxel> free = free_cell.hvoxels(lanes);
      if (own != 0) {
        pieces.clear();
        const auto own_hvoxels = scan_.hvoxels_of(scan_.cells[own - 1]);
        for (const FreeHVoxel& f : free) subtract(f, own_hvoxels, pieces);
        free = pieces;
      }
      extrude(*column, free, p, counts);
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
