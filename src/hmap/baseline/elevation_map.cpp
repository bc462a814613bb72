#include "hmap/baseline/elevation_map.hpp"

#include <cmath>

namespace hmap {

ElevationMap::ElevationMap(const Params& params) : params_(params) { validate(params_); }

std::optional<CellKey> ElevationMap::key_of(double x, double y) const {
  const double fi = std::floor(x / cell_size());
  const double fj = std::floor(y / cell_size());
  // Also false for NaN: comparisons with NaN fail.
  if (!(std::abs(fi) < kMaxKey && std::abs(fj) < kMaxKey)) return std::nullopt;
  return CellKey{static_cast<std::int32_t>(fi), static_cast<std::int32_t>(fj)};
}

Eigen::Vector2d ElevationMap::cell_center(const CellKey& key) const {
  return {(key.i + 0.5) * cell_size(), (key.j + 0.5) * cell_size()};
}

const ElevationCell* ElevationMap::find(const CellKey& key) const {
  const Tile* tile = tiles_.find(tile_of(key));
  if (tile == nullptr) return nullptr;
  const ElevationCell& c = tile->cells[local_index(key)];
  return c.known() ? &c : nullptr;
}

const ElevationCell* ElevationMap::find(double x, double y) const {
  const auto key = key_of(x, y);
  return key ? find(*key) : nullptr;
}

std::optional<double> ElevationMap::elevation_at(double x, double y) const {
  const ElevationCell* c = find(x, y);
  if (c == nullptr) return std::nullopt;
  return c->elevation;
}

ElevationCell& ElevationMap::cell_for_update(const CellKey& key) {
  return tiles_.find_or_create(tile_of(key)).cells[local_index(key)];
}

std::size_t ElevationMap::known_cells() const {
  std::size_t n = 0;
  for_each_cell([&](const CellKey&, const ElevationCell&) { ++n; });
  return n;
}

std::size_t ElevationMap::memory_bytes() const { return tiles_.table_bytes() + tiles_.size() * sizeof(Tile); }

ElevationMapStats ElevationMap::stats() const {
  ElevationMapStats s;
  s.tiles = tiles_.size();
  s.memory_bytes = memory_bytes();
  for_each_cell([&](const CellKey& key, const ElevationCell& c) {
    ++s.cells;
    const double x0 = key.i * cell_size();
    const double y0 = key.j * cell_size();
    s.bounds.extend(Eigen::Vector3d(x0, y0, c.elevation));
    s.bounds.extend(Eigen::Vector3d(x0 + cell_size(), y0 + cell_size(), c.elevation));
  });
  return s;
}

}  // namespace hmap
