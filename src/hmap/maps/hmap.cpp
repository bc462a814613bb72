#include "hmap/maps/hmap.hpp"

#include <cmath>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap {

HMap::HMap(const Params& params) : params_(params) { validate(params_); }

std::optional<CellKey> HMap::key_of(double x, double y) const {
  const double fi = std::floor(x / cell_size());
  const double fj = std::floor(y / cell_size());
  // Also false for NaN: comparisons with NaN fail.
  if (!(std::abs(fi) < kMaxKey && std::abs(fj) < kMaxKey)) return std::nullopt;
  return CellKey{static_cast<std::int32_t>(fi), static_cast<std::int32_t>(fj)};
}

Eigen::Vector2d HMap::cell_center(const CellKey& key) const {
  return {(key.i + 0.5) * cell_size(), (key.j + 0.5) * cell_size()};
}

ColumnView HMap::column(const CellKey& key) const {
  const Tile* tile = tiles_.find(tile_of(key));
  return tile != nullptr ? tile->column(local_index(key)) : ColumnView{};
}

ColumnView HMap::column(double x, double y) const {
  const auto key = key_of(x, y);
  return key ? column(*key) : ColumnView{};
}

TileColumn HMap::column_for_update(const CellKey& key) {
  return {tiles_.find_or_create(tile_of(key)), local_index(key)};
}

const HVoxel* HMap::hvoxel_at(double x, double y, double z) const {
  return column(x, y).find(static_cast<float>(z));
}

bool HMap::empty() const {
  bool empty = true;
  tiles_.for_each([&](const CellKey&, const Tile& tile) { empty = empty && tile.empty(); });
  return empty;
}

void HMap::prune_empty_tiles() {
  tiles_.erase_if([](Tile& tile) {
    tile.shrink_to_fit();
    return tile.empty();
  });
}

std::size_t HMap::memory_bytes() const {
  std::size_t bytes = tiles_.table_bytes() + tiles_.size() * sizeof(Tile);
  tiles_.for_each([&](const CellKey&, const Tile& tile) { bytes += tile.heap_bytes(); });
  return bytes;
}

MapStats HMap::stats() const {
  MapStats s;
  s.tiles = tiles_.size();
  s.memory_bytes = memory_bytes();
  for_each_column([&](const CellKey& key, const ColumnView& c) {
    ++s.cells;
    s.hvoxels += c.size();
    const double x0 = key.i * cell_size();
    const double y0 = key.j * cell_size();
    s.bounds.extend(Eigen::Vector3d(x0, y0, c[0].z_min));
    s.bounds.extend(Eigen::Vector3d(x0 + cell_size(), y0 + cell_size(), c[c.size() - 1].z_max));
  });
  return s;
}

PointCloud recover_points(const HMap& map, double z_step, const MemoryBudget& budget) {
  if (!(z_step > 0.0) || !std::isfinite(z_step)) throw Error("recover_points: z_step must be a positive finite number");
  // Samples z_min + k·z_step for k = 0..⌊h/z_step⌋, then z_max if it was missed: counted in a
  // double first, so that neither the count nor the allocation can overflow.
  double count = 0.0;
  map.for_each_column([&](const CellKey&, const ColumnView& c) {
    for (const HVoxel& v : c) count += std::floor(v.height() / z_step) + 2.0;
  });
  budget.require(count * static_cast<double>(sizeof(Point3f)),
                 format("%.0f points recovered every %g m", count, z_step));
  PointCloud points;
  points.reserve(static_cast<std::size_t>(count));
  map.for_each_column([&](const CellKey& key, const ColumnView& c) {
    const Eigen::Vector2d xy = map.cell_center(key);
    for (const HVoxel& v : c) {
      const double h = v.height();
      const auto steps = static_cast<long>(std::floor(h / z_step));  // bounded by the count above
      for (long k = 0; k <= steps; ++k) {
        points.emplace_back(static_cast<float>(xy.x()), static_cast<float>(xy.y()),
                            static_cast<float>(v.z_min + static_cast<double>(k) * z_step));
      }
      if (static_cast<double>(steps) * z_step < h) {
        points.emplace_back(static_cast<float>(xy.x()), static_cast<float>(xy.y()), v.z_max);
      }
    }
  });
  return points;
}

}  // namespace hmap
