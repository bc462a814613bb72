#include "hmap/maps/map_merge.hpp"

#include <algorithm>
#include <cmath>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap {

namespace {

// The budget is checked after this many tiles (HMap::memory_bytes walks every tile).
constexpr std::size_t kBudgetStride = 256;

void require_same_cell(const HMap& a, const HMap& b, const char* what) {
  if (a.cell_size() != b.cell_size()) {
    throw Error(format("%s: the maps' cells differ (%g m and %g m); build both with the same map.cell_size", what,
                       a.cell_size(), b.cell_size()));
  }
}

}  // namespace

Eigen::AlignedBox2d moved_square_bounds(double x0, double y0, double edge, const PlanarShift& shift) {
  const double c = std::cos(shift.yaw);
  const double sn = std::sin(shift.yaw);
  Eigen::AlignedBox2d box;  // empty
  for (const double cx : {x0, x0 + edge}) {
    for (const double cy : {y0, y0 + edge}) box.extend(Eigen::Vector2d(c * cx - sn * cy + shift.x, sn * cx + c * cy + shift.y));
  }
  return box;
}

void copy_tile(HMap& into, const CellKey& tile_key, const HMap::Tile& tile) {
  for (int local = 0; local < HMap::kTileCells; ++local) {
    const ColumnView source = tile.column(local);
    if (source.empty()) continue;
    TileColumn column = into.column_for_update(HMap::key_in_tile(tile_key, local));
    for (const HVoxel& v : source) column.push_back(v);
  }
}

MapMergeStats merge_map(HMap& into, const HMap& from, const MemoryBudget& budget) {
  require_same_cell(into, from, "merging maps");
  MapMergeStats stats;
  const MapParams& p = into.params().map;
  const auto gap = static_cast<float>(p.point_distance_threshold);
  stats.hvoxels_before = into.stats().hvoxels;
  std::size_t tiles = 0;
  from.for_each_tile([&](const CellKey& tile_key, const HMap::Tile& tile) {
    for (int local = 0; local < HMap::kTileCells; ++local) {
      const ColumnView source = tile.column(local);
      if (source.empty()) continue;
      stats.hvoxels_from += source.size();
      const CellKey key = HMap::key_in_tile(tile_key, local);
      TileColumn column = into.column_for_update(key);
      if (column.size() == 0) {
        for (const HVoxel& v : source) column.push_back(v);
        ++stats.columns_added;
      } else {
        for (const HVoxel& v : source) column.merge(v, gap, p);
        ++stats.columns_merged;
      }
    }
    if (++tiles % kBudgetStride == 0) budget.require(static_cast<double>(into.memory_bytes()), "the merged map");
  });
  budget.require(static_cast<double>(into.memory_bytes()), "the merged map");
  stats.hvoxels_after = into.stats().hvoxels;
  return stats;
}

HMap shifted_map(const HMap& map, const PlanarShift& shift, const MemoryBudget& budget) {
  if (!(std::isfinite(shift.x) && std::isfinite(shift.y) && std::isfinite(shift.z) && std::isfinite(shift.yaw))) {
    throw Error("moving a map: the shift must be finite");
  }
  HMap out(map.params());
  const double s = map.cell_size();
  const double c = std::cos(shift.yaw);
  const double sn = std::sin(shift.yaw);
  const auto dz = static_cast<float>(shift.z);
  const double edge = HMap::kTileSize * s;
  std::size_t tiles = 0;
  // Each source tile fills the result's cells whose centre, moved back, falls in it: every result
  // cell is filled by the one tile under its preimage, so none twice and none skipped.
  map.for_each_tile([&](const CellKey& tile_key, const HMap::Tile& tile) {
    if (tile.empty()) return;
    const double x0 = tile_key.i * edge;
    const double y0 = tile_key.j * edge;
    const Eigen::AlignedBox2d moved = moved_square_bounds(x0, y0, edge, shift);
    const double lo_x = moved.min().x(), lo_y = moved.min().y(), hi_x = moved.max().x(), hi_y = moved.max().y();
    const auto lo = out.key_of(lo_x - s, lo_y - s);
    const auto hi = out.key_of(hi_x + s, hi_y + s);
    if (!lo || !hi) throw Error("moving a map: the shift takes its cells beyond the map's key range");
    for (std::int32_t i = lo->i; i <= hi->i; ++i) {
      for (std::int32_t j = lo->j; j <= hi->j; ++j) {
        const Eigen::Vector2d centre = out.cell_center({i, j});
        const double bx = centre.x() - shift.x;
        const double by = centre.y() - shift.y;
        const auto source = map.key_of(c * bx + sn * by, -sn * bx + c * by);
        if (!source || !(HMap::tile_of(*source) == tile_key)) continue;
        const ColumnView column = tile.column(HMap::local_index(*source));
        if (column.empty()) continue;
        TileColumn target = out.column_for_update({i, j});
        for (HVoxel v : column) {
          v.z_min += dz;
          v.z_max += dz;
          target.push_back(v);
        }
      }
    }
    if (++tiles % kBudgetStride == 0) budget.require(static_cast<double>(out.memory_bytes()), "the moved map");
  });
  out.prune_empty_tiles();
  budget.require(static_cast<double>(out.memory_bytes()), "the moved map");
  return out;
}

HMap crop_map(const HMap& map, const TileRange& range) {
  if (range.i_begin > range.i_end || range.j_begin > range.j_end) {
    throw Error(format("cutting a map: the tile range [%d, %d) x [%d, %d) ends before it begins", range.i_begin,
                       range.i_end, range.j_begin, range.j_end));
  }
  HMap out(map.params());
  map.for_each_tile([&](const CellKey& tile_key, const HMap::Tile& tile) {
    if (range.contains(tile_key)) copy_tile(out, tile_key, tile);
  });
  return out;
}

}  // namespace hmap
